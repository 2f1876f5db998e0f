"""The registry of `train.py stage=...` and of the edit.py / sample.py commands: one entry per
stage holding everything about it (nerfstudio's method_configs). The entries are read before
torch loads, so the runner is a "module:function" string imported only when the stage runs."""
from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from omegaconf import DictConfig

from ngc_gen.lit import kinds

from ..runtime import checks
from ..runtime.errors import ConfigError
from .collection import check_collection
from .export_shape import check_export


@dataclass(frozen=True)
class Stage:
    """One stage or command.

    runner: "module:function" that runs it on the composed config; checkpoint_kind: the kind
    of checkpoint a training stage writes (`ngc_gen.lit.kinds`; a resumed checkpoint must be
    one); steps: it reads trainer.max_steps; mesh_folder: it reads the data config's files;
    extracts: it meshes at extract.resolution; previews: it meshes at
    shape_latent.preview_resolution; check: its own checks of the config before torch loads
    (`ngc_gen.app.runtime.checks`), after the shared ones above."""

    runner: str
    checkpoint_kind: str | None = None
    steps: bool = False
    mesh_folder: bool = False
    extracts: bool = False
    previews: bool = False
    check: Callable[[DictConfig], None] | None = None

    def run(self, cfg: DictConfig):
        return resolve(self.runner)(cfg)


STAGES = {
    "prepare": Stage("ngc_gen.app.stages.prepare_data:prepare_dataset", mesh_folder=True),
    "annotate": Stage("ngc_gen.app.stages.annotate:run_annotate", mesh_folder=True),
    "fit": Stage("ngc_gen.app.stages.fit:run_fit", kinds.FIT, steps=True, mesh_folder=True,
                 extracts=True),
    "shape_latent": Stage("ngc_gen.app.stages.train_shape_latent:run_shape_latent",
                          kinds.SHAPE_LATENT, previews=True, check=checks.check_shape_latent),
    "diffusion": Stage("ngc_gen.app.stages.train_diffusion:run_diffusion", kinds.DIFFUSION,
                       check=checks.check_diffusion_stage),
    "reconstruct": Stage("ngc_gen.app.stages.reconstruct_shapes:run_reconstruct", steps=True,
                         mesh_folder=True, extracts=True, check=checks.check_reconstruct),
    "pipeline": Stage("ngc_gen.app.stages.pipeline:run_pipeline", mesh_folder=True,
                      extracts=True, previews=True, check=check_collection),
}

# the commands beside train.py: edit.py and sample.py (the pipeline runs them as steps too)
COMMANDS = {
    "edit": Stage("ngc_gen.app.stages.edit_shapes:run_edit", check=checks.check_edit),
    "sample": Stage("ngc_gen.app.stages.sample:run_sample", check=checks.check_sample),
    # sample.py mode=export: a shape of any run that holds shapes as a rigged GLB
    "export": Stage("ngc_gen.app.stages.export_shape:run_export", check=check_export),
}


def resolve(name: str):
    """The object a "module:attribute" registry string names."""
    module, attr = name.split(":")
    return getattr(importlib.import_module(module), attr)


def preflight(cfg: DictConfig) -> None:
    """What a training stage checks before it prepares data or makes its run directory:
    trainer.max_steps is a step count, and the checkpoint it would resume from (the run
    directory's last.ckpt, or ckpt_path) loads and is one of this stage's."""
    from ..runtime.resume import resume_point

    checks.trainer_steps(cfg)
    resume_point(cfg, Path(cfg.run_dir), STAGES[cfg.stage].checkpoint_kind)


def check_inputs(cfg: DictConfig) -> None:
    """What train.py checks before torch loads, so a wrong command fails in about a second: the
    stage name, the step count, the resolutions (numbers whose grid fits in memory), the runs
    it reads and the files the data config names (annotation YAMLs, mesh headers, data=folder's
    meshes)."""
    if cfg.stage not in STAGES:
        raise ConfigError("unknown stage", key="stage", value=cfg.stage,
                          fix=f"choose one of {', '.join(STAGES)} (e.g. stage=fit)")
    stage = STAGES[cfg.stage]
    if stage.steps:
        checks.trainer_steps(cfg)
    if stage.extracts and cfg.get("extract") is not None:
        checks.check_extract(cfg)
    if stage.previews and cfg.get("shape_latent") is not None \
            and cfg.shape_latent.get("preview_resolution") is not None:
        checks.check_resolution(cfg, "shape_latent.preview_resolution")
    if stage.checkpoint_kind is not None:
        checks.check_resume_from(cfg, stage.checkpoint_kind)
    if stage.check is not None:
        stage.check(cfg)
    data = cfg.get("data")
    if stage.mesh_folder and data is not None:
        checks.check_data_files(data)


def run_stage(cfg: DictConfig):
    """Check the config (stage, steps, resume point), then run the stage's runner."""
    check_inputs(cfg)  # again for callers other than train.py (pipeline, tests); cheap
    stage = STAGES[cfg.stage]
    if stage.checkpoint_kind is not None:
        if stage.steps:
            preflight(cfg)
        else:  # trainer.max_steps may come from <stage>.max_steps
            from .train_shape_latent import with_stage_steps

            preflight(with_stage_steps(cfg, cfg.stage))
    return stage.run(cfg)
