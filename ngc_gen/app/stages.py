"""The stages `train.py stage=...` runs; each takes the composed Hydra config."""
from __future__ import annotations

import importlib
from pathlib import Path

from omegaconf import DictConfig

from .checks import trainer_steps
from .errors import ConfigError

STAGES = ("prepare", "annotate", "fit", "shape_latent", "diffusion", "reconstruct", "pipeline")
# training stage -> (module, name) of the checkpoint kind its module writes
CHECKPOINT_KINDS = {"fit": ("ngc_gen.lit.autodecoder", "CHECKPOINT_KIND"),
                    "shape_latent": ("ngc_gen.lit.shape_latent", "CHECKPOINT_KIND"),
                    "diffusion": ("ngc_gen.lit.diffusion", "CHECKPOINT_KIND")}


def preflight(cfg: DictConfig) -> None:
    """What a training stage checks before it prepares data or makes its run directory:
    trainer.max_steps is a step count, and the checkpoint it would resume from (the run
    directory's last.ckpt, or ckpt_path) loads and is one of this stage's."""
    from .resume import resume_point

    trainer_steps(cfg)
    module, name = CHECKPOINT_KINDS[cfg.stage]
    resume_point(cfg, Path(cfg.run_dir), getattr(importlib.import_module(module), name))


def check_inputs(cfg: DictConfig) -> None:
    """What train.py checks before torch loads, so a wrong command fails in about a second: the
    stage name, and that data=folder's folder holds meshes."""
    if cfg.stage not in STAGES:
        raise ConfigError("unknown stage", key="stage", value=cfg.stage,
                          fix=f"choose one of {', '.join(STAGES)} (e.g. stage=fit)")
    data = cfg.get("data")
    if (cfg.stage in ("prepare", "annotate", "fit", "reconstruct") and data is not None
            and str(data.get("_target_", "")).endswith(".MeshFolder")):
        from ngc_gen.data.mesh_folder import mesh_files

        mesh_files(data.path)


def run_stage(cfg: DictConfig):
    check_inputs(cfg)  # again for callers other than train.py (pipeline, tests); cheap
    if cfg.stage in ("fit", "reconstruct"):
        trainer_steps(cfg)
    if cfg.stage == "fit":
        preflight(cfg)
    elif cfg.stage in CHECKPOINT_KINDS:  # trainer.max_steps may come from <stage>.max_steps
        from .shape_latent import with_stage_steps

        preflight(with_stage_steps(cfg, cfg.stage))
    if cfg.stage == "prepare":
        from .prepare import prepare_dataset
        return prepare_dataset(cfg)
    if cfg.stage == "annotate":
        from .annotate import run_annotate
        return run_annotate(cfg)
    if cfg.stage == "fit":
        from .fit import run_fit
        return run_fit(cfg)
    if cfg.stage == "shape_latent":
        from .shape_latent import run_shape_latent
        return run_shape_latent(cfg)
    if cfg.stage == "diffusion":
        from .diffusion import run_diffusion
        return run_diffusion(cfg)
    if cfg.stage == "reconstruct":
        from .reconstruct import run_reconstruct
        return run_reconstruct(cfg)
    from .pipeline import run_pipeline
    return run_pipeline(cfg)
