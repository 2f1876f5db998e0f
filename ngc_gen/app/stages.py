"""The stages `train.py stage=...` runs; each takes the composed Hydra config."""
from __future__ import annotations

from omegaconf import DictConfig

from .errors import ConfigError

STAGES = ("prepare", "fit", "shape_latent", "diffusion", "pipeline")


def run_stage(cfg: DictConfig):
    if cfg.stage == "prepare":
        from .prepare import prepare_dataset
        return prepare_dataset(cfg)
    if cfg.stage == "fit":
        from .fit import run_fit
        return run_fit(cfg)
    if cfg.stage == "shape_latent":
        from .shape_latent import run_shape_latent
        return run_shape_latent(cfg)
    if cfg.stage == "diffusion":
        from .diffusion import run_diffusion
        return run_diffusion(cfg)
    if cfg.stage == "pipeline":
        from .pipeline import run_pipeline
        return run_pipeline(cfg)
    raise ConfigError("unknown stage", key="stage", value=cfg.stage,
                      fix=f"choose one of {', '.join(STAGES)} (e.g. stage=fit)")
