"""A folder of the user's meshes: which files count, and the error when there are none.

Light on purpose (pathlib only): `train.py` checks `data.path` with it before torch and
Lightning load, so a wrong path fails in about a second.
"""
from __future__ import annotations

from pathlib import Path

from ngc_gen.data.errors import DataError

MESH_SUFFIXES = {".obj", ".ply", ".stl", ".off", ".glb", ".gltf"}


def mesh_files(folder: str | Path) -> list[Path]:
    """The folder's mesh files, sorted by name; DataError if the folder is missing or empty."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"mesh folder {folder} does not exist",
                        fix="pass data.path=/path/to/your/meshes")
    meshes = sorted(p for p in folder.iterdir() if p.suffix.lower() in MESH_SUFFIXES)
    if not meshes:
        raise DataError(f"no meshes ({', '.join(sorted(MESH_SUFFIXES))}) and no annotations in "
                        f"{folder}", fix="put mesh files in the folder, point data.path at a "
                                         "stage=annotate run directory, or elsewhere")
    return meshes


def run_annotations(folder: str | Path) -> list[Path]:
    """The annotations of a folder without meshes (a `stage=annotate` run directory: each
    `<name>.yaml` names its mesh elsewhere), sorted by name; [] when it has meshes or none."""
    folder = Path(folder)
    if not folder.is_dir() or any(p.suffix.lower() in MESH_SUFFIXES for p in folder.iterdir()):
        return []
    out = []
    for p in sorted(folder.glob("*.yaml")):
        lines = p.read_text(encoding="utf-8", errors="replace").splitlines()
        if any(x.startswith("mesh:") for x in lines) and any(x.startswith("gcs:") for x in lines):
            out.append(p)
    return out
