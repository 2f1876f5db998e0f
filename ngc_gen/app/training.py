"""What the training stages share: the run directory, the module of a config group, and a
Lightning trainer built from the config (callbacks, logger, quiet console, resume)."""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import NamedTuple

import hydra
from lightning.pytorch.callbacks import Callback
from omegaconf import DictConfig, OmegaConf

from ngc_gen.data.atomic import atomic_write_text


def start_run(cfg: DictConfig) -> Path:
    """Create the run directory and record the resolved config in it first."""
    run_dir = Path(cfg.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(run_dir / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))
    return run_dir


class _DropTip(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "litlogger" not in record.getMessage()


def quiet_lightning() -> None:
    """One copy of each Lightning message: under Hydra the root handler already prints it (and
    writes it to <run>/<job>.log), so Lightning's own console handler only repeats it. Its
    advertising tip and a deprecation warning it raises inside itself (torch's LeafSpec) say
    nothing about the run and are dropped too."""
    import warnings

    import lightning  # noqa: F401  (installs its handler, which is then removed)

    if logging.getLogger().hasHandlers():
        lg = logging.getLogger("lightning")
        for h in [h for h in lg.handlers if type(h) is logging.StreamHandler]:
            lg.removeHandler(h)
    tip = logging.getLogger("lightning.pytorch.utilities.rank_zero")
    if not any(isinstance(f, _DropTip) for f in tip.filters):
        tip.addFilter(_DropTip())
    warnings.filterwarnings("ignore", message=r".*isinstance\(treespec, LeafSpec\)")


def instantiate_group(node: DictConfig, runner_keys: tuple[str, ...] = (), **runtime):
    """The object a config group option names by `_target_` (its interpolations resolved in the
    whole config), built with `runtime` arguments (sizes known only from the data); the group's
    `runner_keys` are settings the stage reads itself and are left out. Arguments arrive as
    plain dicts and lists (`_convert_="all"`), so hyper-parameters a module records stay
    loadable with weights_only=True."""
    d = OmegaConf.to_container(node, resolve=True)
    for k in runner_keys:
        d.pop(k, None)
    return hydra.utils.instantiate(d, _convert_="all", **runtime)


def build_callbacks(cfg: DictConfig) -> list:
    """The Lightning callbacks of `cfg.callbacks` (an entry set to null is dropped).
    `every_n_train_steps: null` means trainer.max_steps / 4, at most 500; the progress bar is
    dropped when trainer.enable_progress_bar is false (Lightning refuses both at once)."""
    from lightning.pytorch.callbacks import ProgressBar

    out = []
    for node in (cfg.get("callbacks") or {}).values():
        if node is None:
            continue
        kw = {}
        if "every_n_train_steps" in node and node.every_n_train_steps is None:
            kw["every_n_train_steps"] = max(1, min(500, int(cfg.trainer.max_steps) // 4))
        cb = hydra.utils.instantiate(node, **kw)
        if isinstance(cb, ProgressBar) and not cfg.trainer.get("enable_progress_bar", True):
            continue
        out.append(cb)
    return out


class StartStep(Callback):
    """Records the optimizer step training starts from (the checkpoint's when resuming)."""

    step: int | None = None

    def on_train_start(self, trainer, pl_module) -> None:
        self.step = int(trainer.global_step)


def build_trainer(cfg: DictConfig, run_dir: Path, extra_callbacks=()):
    """The Lightning trainer of `cfg.trainer` with `cfg.callbacks` and `cfg.logger`."""
    quiet_lightning()
    logger = hydra.utils.instantiate(cfg.logger) if cfg.get("logger") else False
    callbacks = build_callbacks(cfg) + list(extra_callbacks)
    return hydra.utils.instantiate(cfg.trainer, callbacks=callbacks, logger=logger,
                                   default_root_dir=str(run_dir))


def resume_checkpoint(cfg: DictConfig) -> str | None:
    """`ckpt_path`: a checkpoint file or a run directory (its checkpoints/last.ckpt), or null."""
    from ngc_gen.lit.checkpoint import resolve_checkpoint

    if cfg.get("ckpt_path") is None:
        return None
    return str(resolve_checkpoint(cfg.ckpt_path, what="checkpoint to resume from",
                                  fix="pass ckpt_path=<run dir> or <run>/checkpoints/last.ckpt of "
                                      "an interrupted run of the same stage"))


class Trained(NamedTuple):
    trainer: object
    seconds: float
    start_step: int  # the step training started from: 0, or the resumed checkpoint's step


def train(cfg: DictConfig, run_dir: Path, module, *data, **fit_kwargs) -> Trained:
    """trainer.fit, resuming from `ckpt_path` if set; (trainer, seconds, start step)."""
    ckpt = resume_checkpoint(cfg)
    start = StartStep()
    trainer = build_trainer(cfg, run_dir, [start])
    t0 = time.perf_counter()
    trainer.fit(module, *data, ckpt_path=ckpt, **fit_kwargs)
    return Trained(trainer, time.perf_counter() - t0, start.step)
