"""Your own collection in one command (`experiment=collection`, a pipeline with an `annotate`
step): what is checked before anything runs, what is checked after the annotation, and the
two of the user's meshes the interpolation runs between.

    python train.py experiment=collection data.path=DIR annotate.template=T

The checks before torch loads read file names only (no mesh): the template exists, the folder
holds at least MIN_MESHES meshes. After `annotate`, at least MIN_MESHES meshes must have
matched the template.
"""
from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from ngc_gen import workspace
from ngc_gen.data.errors import DataError

# a generator learns from several shapes; the small-collection recipe is measured on 5-30
MIN_MESHES = 2


def _annotate_step(cfg: DictConfig) -> bool:
    p = cfg.get("pipeline") or {}
    return "annotate" in list(p.get("steps") or [])


def check_collection(cfg: DictConfig) -> None:
    """Before anything runs (no torch, no mesh read): for a pipeline that annotates a folder,
    annotate.template names a file and data.path holds at least MIN_MESHES meshes."""
    if not _annotate_step(cfg):
        return
    from ngc_gen.data.mesh_folder import mesh_files

    template = cfg.get("annotate", {}).get("template")
    if not template:
        raise DataError("no template: the collection's meshes get the template's GCs",
                        field="annotate.template",
                        fix="pass annotate.template=datasets/animals/quadruped_transfer.yaml "
                            "(quadrupeds), or any annotated mesh's YAML (docs/transfer.md)")
    if not Path(str(template)).expanduser().is_file():
        raise DataError(f"template {template} does not exist", field="annotate.template",
                        fix="pass annotate.template=datasets/animals/quadruped_transfer.yaml "
                            "(quadrupeds), or the path of any annotated mesh's YAML")
    path = cfg.get("data", {}).get("path")
    meshes = mesh_files(path)
    if len(meshes) < MIN_MESHES:
        raise DataError(f"the collection {path} has {len(meshes)} mesh ({meshes[0].name}); a "
                        f"generator needs at least {MIN_MESHES}", field="data.path",
                        fix="put more meshes of the same kind in the folder (5-30 for the "
                            "small-collection recipe), or fit the one mesh: python train.py "
                            f"stage=fit data=folder data.path={path}")


def check_annotated(rows: list[dict], folder) -> None:
    """After the annotate step: at least MIN_MESHES meshes matched the template (rows: the
    annotate stage's, a row with `error` is a refused mesh)."""
    ok = [r for r in rows if "error" not in r]
    if len(ok) >= MIN_MESHES:
        return
    refused = [r for r in rows if "error" in r]
    why = "; ".join(f"{r['mesh']}: {r['error']}" for r in refused[:2])
    what = ("every mesh was refused by the template" if not ok else
            f"only {ok[0]['mesh']} matched the template ({len(refused)} refused)")
    raise DataError(f"{what} ({why})", field="annotate.template",
                    fix=f"check that the meshes in {folder} are of the template's kind; give "
                        "their axes (annotate.up=+y annotate.front=+z) if detection fails, or "
                        "another template")


def interpolation_pair(shape_latent_dir: Path) -> tuple[str, str]:
    """Two of the user's meshes to interpolate between: the first training shape and the one
    whose latent lies farthest from it (the most different pair through the first)."""
    import torch

    d = torch.load(workspace.latents(shape_latent_dir), weights_only=True)
    names, z = d["names"], d["latents"].float()
    far = int(torch.linalg.vector_norm(z - z[0], dim=1).argmax())
    return str(names[0]), str(names[far if far != 0 else min(1, len(names) - 1)])


def collection_row(annotate_dir: Path, limit: int = 4):
    """(meshes, up) of the overview's first row: the first annotated meshes as written (in the
    template's frame: `Annotation.load_mesh` turns them), and that frame's up (None: none)."""
    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.mesh_folder import run_annotations

    meshes, up = [], None
    for y in run_annotations(annotate_dir)[:limit]:
        try:
            ann = load_annotation(y)
            meshes.append(ann.load_mesh()[0])
        except (DataError, OSError):
            continue
        up = up or (list(ann.frame["up"]) if ann.frame else None)
    return meshes, up
