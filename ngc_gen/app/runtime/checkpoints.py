"""Which checkpoint a command means: edit.py, the editor and mix sources name a fit run, a
checkpoint file or a sample.py output folder; this resolves all three to one file."""
from __future__ import annotations

from pathlib import Path


def fit_checkpoint(run) -> Path:
    """The checkpoint edit.py reads: a fit run directory (its checkpoints/last.ckpt), a
    checkpoint file, or a sample.py output directory (its shapes.ckpt)."""
    from ngc_gen.lit.peek import resolve_checkpoint

    if run is not None and Path(run).is_dir() and (Path(run) / "shapes.ckpt").is_file() \
            and not (Path(run) / "checkpoints").is_dir():
        return Path(run) / "shapes.ckpt"
    return resolve_checkpoint(run, what="fit run",
                              fix="pass run=<dir> (or its checkpoints/last.ckpt) of a `train.py "
                                  "stage=fit` run, or run=<a sample.py output directory>")
