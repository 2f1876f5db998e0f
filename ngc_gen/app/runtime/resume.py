"""What lets a killed training run continue where it stopped when the same command runs again.

- The checkpoint to resume: `<run_dir>/checkpoints/last.ckpt` when the run directory has one
  (`resume: true`, the default), else `ckpt_path` (another run's checkpoint), else none. It is
  loaded with weights_only=True first and must be a checkpoint of this stage's module.
- Checkpoints are written atomically (temp file + rename), so a kill -9 mid-write leaves the
  previous complete `last.ckpt`, never a truncated one.
- The CSV log keeps its rows up to the resumed step (Lightning's CSVLogger deletes the file of
  an existing log folder), so the history of a resumed run is whole and has no repeated steps.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import NamedTuple

from lightning.pytorch.loggers import CSVLogger
from lightning.pytorch.plugins.io import TorchCheckpointIO

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write
from ngc_gen.data.errors import DataError

from .errors import ConfigError


class Resume(NamedTuple):
    path: str | None  # the checkpoint Lightning resumes from (None: a fresh start)
    step: int         # its global step (0 for a fresh start)


def checkpoint_step(path: Path, kind: str | None, fix: str) -> int:
    """The global step of a Lightning checkpoint, loaded with weights_only=True; DataError if it
    is unreadable (truncated, not a checkpoint) or of another module than `kind`."""
    from ngc_gen.lit.checkpoint import load_checkpoint_dict

    ckpt = load_checkpoint_dict(path, fix)
    got = ckpt.get("hyper_parameters", {}).get("checkpoint_kind")
    if kind is not None and got != kind:
        raise DataError(f"{path} is a checkpoint of another stage (kind {got!r}, this stage "
                        f"trains {kind!r})", fix=fix)
    if "global_step" not in ckpt or "state_dict" not in ckpt:
        raise DataError(f"{path} is not a Lightning training checkpoint (no global_step)",
                        fix=fix)
    return int(ckpt["global_step"])


def resume_point(cfg, run_dir, kind: str | None) -> Resume:
    """Where this run starts (see the module docstring); ConfigError when `resume=false` would
    overwrite the checkpoints of an earlier run in the same directory."""
    from ngc_gen.lit.checkpoint import resolve_checkpoint

    own = workspace.last_checkpoint(run_dir)
    if own.is_file():
        if not cfg.get("resume", True):
            raise ConfigError(f"{run_dir} already holds the checkpoints of an earlier run",
                              key="resume", value=False,
                              fix="pass resume=true to continue it, or another hydra.run.dir "
                                  "for a new run")
        return Resume(str(own), checkpoint_step(
            own, kind, fix=f"delete {own} to start over (it is the run's latest checkpoint)"))
    if cfg.get("ckpt_path") is None:
        return Resume(None, 0)
    fix = ("pass ckpt_path=<run dir> or <run>/checkpoints/last.ckpt of an interrupted run of the "
           "same stage")
    path = resolve_checkpoint(cfg.ckpt_path, what="checkpoint to resume from", fix=fix)
    return Resume(str(path), checkpoint_step(path, kind, fix))


class AtomicCheckpointIO(TorchCheckpointIO):
    """torch.save into a temp file beside the checkpoint, then rename it into place."""

    def save_checkpoint(self, checkpoint, path, storage_options=None) -> None:
        import torch

        buffer = io.BytesIO()
        torch.save(checkpoint, buffer)
        atomic_write(path, lambda f: f.write(buffer.getbuffer()))


class ResumableCSVLogger(CSVLogger):
    """Lightning's CSVLogger (logs/metrics.csv, hparams.yaml), except that an existing
    metrics.csv is kept up to the step a run resumes from (`keep_until`, set by the stage)
    instead of being deleted; a fresh start (keep_until 0) replaces it."""

    keep_until: int = 0

    @property
    def experiment(self):
        from lightning.pytorch.utilities import rank_zero_only

        first = self._experiment is None and rank_zero_only.rank == 0
        path = Path(self.log_dir) / "metrics.csv"
        rows = kept_rows(path, self.keep_until) if first and path.is_file() else None
        writer = super().experiment  # deletes an existing metrics.csv
        if rows:
            header, body = rows
            writer.metrics_keys = list(header)
            with open(writer.metrics_file_path, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=header)
                w.writeheader()
                w.writerows(body)
        return writer


def kept_rows(path: Path, until: int):
    """(header, rows with step < until) of a CSV log; None if nothing is kept."""
    if until <= 0:
        return None
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        header = reader.fieldnames or []
        rows = [r for r in reader if r.get("step", "") != "" and int(float(r["step"])) < until]
    return (header, rows) if header and rows else None
