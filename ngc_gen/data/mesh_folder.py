"""A folder of the user's meshes: which files count, and the error when there are none.

Light on purpose (pathlib only): `train.py` checks `data.path` with it before torch and
Lightning load, so a wrong path fails in about a second.
"""
from __future__ import annotations

from pathlib import Path

from ngc_gen.data.errors import DataError

MESH_SUFFIXES = {".obj", ".ply", ".stl", ".off", ".glb", ".gltf"}


# what a run directory holds besides annotations (a stage's record of its settings)
RUN_RECORDS = {"config.yaml"}


def annotation_files(folder: str | Path) -> list[Path]:
    """The annotation YAMLs of a `train.py stage=annotate` run directory: a folder with no
    meshes of its own whose <name>.yaml files name meshes elsewhere; [] for a mesh folder."""
    folder = Path(folder)
    if not folder.is_dir() or any(p.suffix.lower() in MESH_SUFFIXES for p in folder.iterdir()):
        return []
    return sorted(p for p in folder.glob("*.yaml") if p.name not in RUN_RECORDS)


def mesh_files(folder: str | Path, annotated_run: bool = False) -> list[Path]:
    """The folder's mesh files, sorted by name; DataError if the folder is missing or empty.
    With `annotated_run`, a folder of annotations only (an annotate run, `annotation_files`)
    is not empty: [] then."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"mesh folder {folder} does not exist",
                        fix="pass data.path=/path/to/your/meshes")
    meshes = sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES)
    if not meshes and annotated_run and annotation_files(folder):
        return []
    if not meshes:
        raise DataError(f"no meshes ({', '.join(sorted(MESH_SUFFIXES))}) in {folder}",
                        fix="put mesh files in the folder or point data.path elsewhere")
    return meshes
