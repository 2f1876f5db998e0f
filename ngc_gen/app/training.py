"""What the training stages share: the run directory and a Lightning trainer built from the
config (checkpoints, logger, quiet console)."""
from __future__ import annotations

import logging
import time
from pathlib import Path

import hydra
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


def build_trainer(cfg: DictConfig, run_dir: Path):
    """The Lightning trainer of `cfg.trainer` with `cfg.logger`; checkpoints/last.ckpt and
    best.ckpt (lowest train/loss) every max_steps/4 steps (at most 500), so a resume loses
    little."""
    from lightning.pytorch.callbacks import ModelCheckpoint

    quiet_lightning()
    every = max(1, min(500, int(cfg.trainer.max_steps) // 4))
    callbacks = [
        ModelCheckpoint(dirpath=run_dir / "checkpoints", filename="best", monitor="train/loss",
                        mode="min", save_top_k=1, save_last=True, every_n_train_steps=every),
    ]
    logger = hydra.utils.instantiate(cfg.logger) if cfg.get("logger") else False
    return hydra.utils.instantiate(cfg.trainer, callbacks=callbacks, logger=logger,
                                   default_root_dir=str(run_dir))


def train(cfg: DictConfig, run_dir: Path, module, *data, **fit_kwargs):
    """trainer.fit (resuming from cfg.ckpt_path if set); returns (trainer, seconds)."""
    trainer = build_trainer(cfg, run_dir)
    t0 = time.perf_counter()
    trainer.fit(module, *data, ckpt_path=cfg.ckpt_path, **fit_kwargs)
    return trainer, time.perf_counter() - t0
