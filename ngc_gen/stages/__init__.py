"""The stages `train.py stage=...` runs; each takes the composed Hydra config."""
from __future__ import annotations

from omegaconf import DictConfig

STAGES = ("prepare", "fit")


def run_stage(cfg: DictConfig):
    if cfg.stage == "prepare":
        from .prepare import prepare_dataset
        return prepare_dataset(cfg)
    if cfg.stage == "fit":
        from .fit import run_fit
        return run_fit(cfg)
    raise ValueError(f"unknown stage {cfg.stage!r}; choose one of {', '.join(STAGES)}")
