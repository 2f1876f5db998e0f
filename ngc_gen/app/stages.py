"""The stages `train.py stage=...` runs; each takes the composed Hydra config."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from omegaconf import DictConfig, ListConfig

from .checks import check_extract, check_resolution, trainer_steps
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


EXTRACTS = ("fit", "reconstruct", "pipeline")       # mesh at extract.resolution
PREVIEWS = ("shape_latent", "pipeline")             # mesh at shape_latent.preview_resolution


# a stage's checkpoint_kind (`Stage.checkpoint_kind`, resolved lazily) as a string, for the
# torch-free checks; tests/app keep them equal to the modules' CHECKPOINT_KIND
KIND_OF = {"fit": "ngc_gen.autodecoder", "shape_latent": "ngc_gen.shape_latent",
           "diffusion": "ngc_gen.diffusion"}


def check_runs(cfg: DictConfig) -> None:
    """The runs a command names exist and are of the right kind, read without torch
    (`ngc_gen.lit.peek`): the checkpoint to resume from, diffusion's shape-latent run and
    shape_latent's init_decoder."""
    from ngc_gen.lit.peek import KINDS, check_kind, resolve_checkpoint

    if cfg.get("ckpt_path") is not None and cfg.stage in KIND_OF:
        fix = ("pass ckpt_path=<run dir> or <run>/checkpoints/last.ckpt of an interrupted run "
               "of the same stage")
        kind = KIND_OF[cfg.stage]
        check_kind(resolve_checkpoint(cfg.ckpt_path, what="checkpoint to resume from", fix=fix),
                   {kind: KINDS[kind]}, fix)
    if cfg.stage == "diffusion":
        fix = ("pass the run directory (or checkpoints/last.ckpt) of a `train.py "
               "stage=shape_latent` run")
        path = resolve_checkpoint(cfg.get("shape_latent_run"), fix, "shape-latent run")
        check_kind(path, {"ngc_gen.shape_latent": KINDS["ngc_gen.shape_latent"]}, fix)
    init = cfg.get("shape_latent", {}).get("init_decoder") if cfg.stage == "shape_latent" \
        else None
    if init is not None:
        fix = "pass shape_latent.init_decoder=<a `train.py stage=fit` run or its last.ckpt>"
        check_kind(resolve_checkpoint(init, fix, "fit run"),
                   {"ngc_gen.autodecoder": KINDS["ngc_gen.autodecoder"]}, fix)


def check_diffusion(d) -> None:
    """diffusion.standardise and diffusion.pca_complete name known choices."""
    from ngc_gen.lit.diffusion_options import PCA_COMPLETE, STANDARDISE

    for key, allowed in (("standardise", STANDARDISE), ("pca_complete", PCA_COMPLETE)):
        if d.get(key) is not None and d.get(key) not in allowed:
            raise ConfigError("unknown choice", key=f"diffusion.{key}", value=d.get(key),
                              fix=f"choose one of {', '.join(allowed)}")
    check_pose_transfer(d.get("pose_transfer"))


def check_pose_transfer(pt) -> None:
    """diffusion.pose_transfer: null, or bodies (a non-empty list of names) and the GC template
    file the shapes were made with (its GCs' parents)."""
    if not pt:
        return
    key = "diffusion.pose_transfer"
    bodies = pt.get("bodies")
    if not isinstance(bodies, (list, tuple, ListConfig)) or not bodies \
            or not all(isinstance(b, str) and b for b in bodies):
        raise ConfigError("needs a non-empty list of body names", key=f"{key}.bodies",
                          value=bodies, fix="list the names the shape names start with, e.g. "
                          "diffusion.pose_transfer.bodies=[wolf,horse]")
    if pt.get("poses") not in (None, "missing", "all"):
        raise ConfigError("must be missing (the poses a body lacks) or all", key=f"{key}.poses",
                          value=pt.get("poses"), fix=f"pass {key}.poses=missing")
    template = pt.get("template")
    if not template or not Path(str(template)).is_file():
        raise ConfigError("GC template file not found", key=f"{key}.template", value=template,
                          fix="pass the template the shapes were made with (the animals': "
                          "datasets/animals/quadruped.yaml), or diffusion.pose_transfer=null")


def check_inputs(cfg: DictConfig) -> None:
    """What train.py checks before torch loads, so a wrong command fails in about a second: the
    stage name, the step count, the resolutions (numbers whose grid fits in memory), and the
    files the data config names (annotation YAMLs, mesh headers, data=folder's meshes)."""
    if cfg.stage not in STAGES:
        raise ConfigError("unknown stage", key="stage", value=cfg.stage,
                          fix=f"choose one of {', '.join(STAGES)} (e.g. stage=fit)")
    stage = STAGES[cfg.stage]
    if stage.steps:
        trainer_steps(cfg)
    if cfg.stage in EXTRACTS and cfg.get("extract") is not None:
        check_extract(cfg)
    if cfg.stage in PREVIEWS and cfg.get("shape_latent") is not None \
            and cfg.shape_latent.get("preview_resolution") is not None:
        check_resolution(cfg, "shape_latent.preview_resolution")
    check_runs(cfg)
    if cfg.stage == "diffusion" and cfg.get("diffusion") is not None:
        check_diffusion(cfg.diffusion)
    data = cfg.get("data")
    if (stage.mesh_folder or cfg.stage == "pipeline") and data is not None:
        from omegaconf import OmegaConf

        from ngc_gen.data.preflight import check_data

        check_data(OmegaConf.to_container(data, resolve=True, throw_on_missing=True))
    if cfg.stage == "shape_latent" and data is not None:
        from omegaconf import OmegaConf

        from ngc_gen.data.preflight import check_frames

        check_frames(OmegaConf.to_container(data, resolve=True, throw_on_missing=True))
    if cfg.stage == "pipeline" and cfg.get("pipeline") is not None:
        from .collection import check_collection

        check_collection(cfg)


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
