"""Every file a run directory holds, named once (DeepSDF's workspace.py): runners, checks and
loaders ask here for a path instead of spelling a file name. Standard library only, so any
layer and the entry points' checks before torch can use it.

A run directory is what `train.py` (hydra.run.dir), `edit.py` and `sample.py` (out_dir) write:

    config.yaml           the composed config, resolved         (train.py)
    seeds.json            the seeds the run used                (train.py)
    checkpoints/last.ckpt the checkpoint a rerun resumes from   (training stages)
    metrics.json          the run's numbers                     (every stage and edit.py)
    meshes/<name>.ply     extracted meshes                      (fit, shape_latent, reconstruct)
    latents.pt            one latent per shape                  (shape_latent, reconstruct, sample.py)
    shapes.ckpt           shapes in the fit format, for edit.py (reconstruct, sample.py)
    summary.json          what a sample.py mode or the pipeline made
    condition.yaml        the GCs sample.py mode=condition was given, as read
    edited.yaml           the edited GCs                        (edit.py)
    deformed.ply, undeformed.ply, program.yaml   the edited and unedited meshes, the program
                                                 as run (edit.py)
    <stage>.png           the run's picture: meshes.png (fit), reconstruct.png, edit.png,
                          shapes.png (sample.py), overview.png (pipeline)
    .lock                 the owner while a command works in it
"""
from __future__ import annotations

from pathlib import Path

CONFIG = "config.yaml"
SEEDS = "seeds.json"
CHECKPOINTS = "checkpoints"
LAST = "last.ckpt"
METRICS = "metrics.json"
MESHES = "meshes"
LATENTS = "latents.pt"
SHAPES_CHECKPOINT = "shapes.ckpt"
SUMMARY = "summary.json"
CONDITION = "condition.yaml"
EDITED = "edited.yaml"
DEFORMED = "deformed.ply"
UNDEFORMED = "undeformed.ply"
PROGRAM = "program.yaml"
LOCK = ".lock"
PICTURES = {"fit": "meshes.png", "reconstruct": "reconstruct.png", "edit": "edit.png",
            "sample": "shapes.png", "pipeline": "overview.png"}


def config(run) -> Path:
    return Path(run) / CONFIG


def seeds(run) -> Path:
    return Path(run) / SEEDS


def checkpoints(run) -> Path:
    """The folder Lightning's ModelCheckpoint writes (conf/callbacks/default.yaml)."""
    return Path(run) / CHECKPOINTS


def last_checkpoint(run) -> Path:
    return checkpoints(run) / LAST


def metrics(run) -> Path:
    return Path(run) / METRICS


def meshes(run) -> Path:
    return Path(run) / MESHES


def mesh(run, name: str) -> Path:
    return meshes(run) / f"{name}.ply"


def latents(run) -> Path:
    return Path(run) / LATENTS


def shapes_checkpoint(run) -> Path:
    return Path(run) / SHAPES_CHECKPOINT


def summary(run) -> Path:
    return Path(run) / SUMMARY


def condition(run) -> Path:
    return Path(run) / CONDITION


def edited(run) -> Path:
    return Path(run) / EDITED


def lock(run) -> Path:
    return Path(run) / LOCK


def picture(run, stage: str) -> Path:
    """The picture `stage` (a key of PICTURES) draws into its run directory."""
    return Path(run) / PICTURES[stage]
