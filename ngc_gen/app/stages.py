"""The stages `train.py stage=...` runs; each takes the composed Hydra config."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from omegaconf import DictConfig

from .checks import trainer_steps
from .errors import ConfigError



@dataclass(frozen=True)
class Stage:
    """One entry of the registry. Names are "module:attribute" strings, imported when the stage
    runs, so train.py checks a command before torch and Lightning load.

    runner: the function that runs the stage on the composed config; checkpoint_kind: the kind
    of checkpoint a training stage writes (checked before resuming); steps: the stage reads
    trainer.max_steps; mesh_folder: the stage reads data=folder's meshes."""

    runner: str
    checkpoint_kind: str | None = None
    steps: bool = False
    mesh_folder: bool = False


STAGES = {
    "prepare": Stage("ngc_gen.app.prepare:prepare_dataset", mesh_folder=True),
    "annotate": Stage("ngc_gen.app.annotate:run_annotate", mesh_folder=True),
    "fit": Stage("ngc_gen.app.fit:run_fit", "ngc_gen.lit.autodecoder:CHECKPOINT_KIND",
                 steps=True, mesh_folder=True),
    "shape_latent": Stage("ngc_gen.app.shape_latent:run_shape_latent",
                          "ngc_gen.lit.shape_latent:CHECKPOINT_KIND"),
    "diffusion": Stage("ngc_gen.app.diffusion:run_diffusion",
                       "ngc_gen.lit.diffusion:CHECKPOINT_KIND"),
    "reconstruct": Stage("ngc_gen.app.reconstruct:run_reconstruct", steps=True,
                         mesh_folder=True),
    "pipeline": Stage("ngc_gen.app.pipeline:run_pipeline"),
}


def resolve(name: str):
    """The object a "module:attribute" registry string names."""
    module, attr = name.split(":")
    return getattr(importlib.import_module(module), attr)


def preflight(cfg: DictConfig) -> None:
    """What a training stage checks before it prepares data or makes its run directory:
    trainer.max_steps is a step count, and the checkpoint it would resume from (the run
    directory's last.ckpt, or ckpt_path) loads and is one of this stage's."""
    from .resume import resume_point

    trainer_steps(cfg)
    resume_point(cfg, Path(cfg.run_dir), resolve(STAGES[cfg.stage].checkpoint_kind))


def check_inputs(cfg: DictConfig) -> None:
    """What train.py checks before torch loads, so a wrong command fails in about a second: the
    stage name, and that data=folder's folder holds meshes."""
    if cfg.stage not in STAGES:
        raise ConfigError("unknown stage", key="stage", value=cfg.stage,
                          fix=f"choose one of {', '.join(STAGES)} (e.g. stage=fit)")
    data = cfg.get("data")
    if (STAGES[cfg.stage].mesh_folder and data is not None
            and str(data.get("_target_", "")).endswith(".MeshFolder")):
        from ngc_gen.data.mesh_folder import mesh_files

        mesh_files(data.path)


def run_stage(cfg: DictConfig):
    """Check the config (stage, steps, resume point), then run the stage's runner."""
    check_inputs(cfg)  # again for callers other than train.py (pipeline, tests); cheap
    stage = STAGES[cfg.stage]
    if stage.steps:
        trainer_steps(cfg)
    if stage.checkpoint_kind is not None:
        if stage.steps:
            preflight(cfg)
        else:  # trainer.max_steps may come from <stage>.max_steps
            from .shape_latent import with_stage_steps

            preflight(with_stage_steps(cfg, cfg.stage))
    return resolve(stage.runner)(cfg)
