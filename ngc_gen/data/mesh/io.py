"""Mesh loading, validation and normalisation.

``load_mesh`` reads anything trimesh reads (OBJ/PLY/STL/OFF/GLB, a scene is concatenated) with
``process=False`` so vertex order is the file's, and checks what later stages rely on: faces
exist, vertices are finite, face indices are in range. A mesh path may also name a file shipped
inside an installed package (``pyvista:ant.ply``); such files are read in place, never downloaded.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np
import trimesh

from ngc_gen.data.errors import DataError

from .gltf_header import check_gltf_file

# scheme -> (package, sub-folder holding the shipped files)
RESOURCE_SCHEMES: dict[str, tuple[str, str]] = {"pyvista": ("pyvista", "examples")}

_READ_FIX = "check that the file is a complete mesh in a format trimesh reads (OBJ/PLY/STL/OFF/GLB)"


def is_resource(spec: str | os.PathLike) -> bool:
    """True if ``spec`` is a package resource such as ``pyvista:ant.ply``."""
    if not isinstance(spec, str) or ":" not in spec:
        return False
    return spec.split(":", 1)[0] in RESOURCE_SCHEMES


def resource_path(spec: str) -> Path:
    """Path of a shipped file named ``scheme:file`` inside its installed package.

    The package is located with ``importlib.util.find_spec``, which does not import it (pyvista
    would pull in VTK). Raises DataError for an unknown scheme, a missing package or file.
    """
    scheme, name = spec.split(":", 1)
    if scheme not in RESOURCE_SCHEMES:
        raise DataError(
            f"unknown resource scheme '{scheme}' in '{spec}'",
            fix=f"use one of {sorted(RESOURCE_SCHEMES)} or a file path",
        )
    if not name or Path(name).name != name:
        raise DataError(
            f"resource name '{name}' in '{spec}' must be a plain file name",
            fix=f"write it as '{scheme}:<file>', e.g. 'pyvista:ant.ply'",
        )
    package, sub = RESOURCE_SCHEMES[scheme]
    found = importlib.util.find_spec(package)
    if found is None or not found.submodule_search_locations:
        raise DataError(
            f"package '{package}' needed for '{spec}' is not installed",
            fix=f"install the project's dependencies (pip install -e .) so '{package}' is present",
        )
    folder = Path(list(found.submodule_search_locations)[0]) / sub
    path = folder / name
    if not path.is_file():
        shipped = sorted(p.name for p in folder.glob("*") if p.suffix in {".ply", ".obj", ".stl", ".off"})
        raise DataError(
            f"'{name}' is not shipped with {package} (looked in {folder})",
            path=spec,
            fix=f"use one of {shipped}",
        )
    return path


def resolve_mesh_path(spec: str | os.PathLike, base_dir: str | os.PathLike | None = None) -> Path:
    """Resolve a mesh reference: a package resource, an absolute path, or a path relative to
    ``base_dir`` (the annotation file's folder). Does not check that a plain file exists."""
    if is_resource(spec):
        return resource_path(str(spec))
    path = Path(os.path.expanduser(os.fspath(spec)))
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    return path


def load_mesh(path: str | os.PathLike) -> trimesh.Trimesh:
    """Load and validate a triangle mesh.

    path: a file (any format trimesh reads) or a resource ``scheme:file``.
    Returns a ``trimesh.Trimesh`` built with ``process=False``: vertices (V, 3) float64 and
    faces (F, 3) int64 exactly as in the file (a scene's meshes are concatenated with their
    transforms applied). Raises DataError for a missing or unreadable file, no faces, NaN/inf
    vertices, or face indices out of range.
    """
    file = resolve_mesh_path(path)
    if not file.is_file():
        raise DataError(
            "mesh file not found" if not file.exists() else "mesh path is not a file",
            path=file,
            fix="check the path (relative paths in an annotation are relative to the YAML file)",
        )
    if file.suffix.lower() in (".gltf", ".glb"):
        check_gltf_file(file)  # what trimesh does not check (a node tree with a circle)
    try:
        loaded = trimesh.load(file, process=False)
        if isinstance(loaded, trimesh.Scene):
            loaded = loaded.to_mesh()
    except Exception as e:  # trimesh raises many types (ValueError, IndexError, KeyError, ...)
        raise DataError(f"could not read the mesh ({type(e).__name__}: {e})", path=file, fix=_READ_FIX) from e
    faces = getattr(loaded, "faces", None)
    if not isinstance(loaded, trimesh.Trimesh) or faces is None or len(faces) == 0:
        raise DataError(
            f"the file holds no triangles (read as {type(loaded).__name__})",
            path=file,
            fix="give a surface mesh with faces; point clouds and empty files cannot be prepared",
        )
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(faces)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise DataError(f"faces have shape {faces.shape}, expected (F, 3)", path=file, fix="triangulate the mesh")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise DataError(
            f"{int(bad.sum())} of {len(vertices)} vertices are NaN or infinite (first: vertex {int(np.argmax(bad))})",
            path=file,
            fix="repair or re-export the mesh so every vertex coordinate is a finite number",
        )
    lo, hi = int(faces.min()), int(faces.max())
    if lo < 0 or hi >= len(vertices):
        raise DataError(
            f"face indices span [{lo}, {hi}] but the mesh has {len(vertices)} vertices",
            path=file,
            fix="re-export the mesh; its faces refer to vertices that do not exist",
        )
    return trimesh.Trimesh(vertices=vertices, faces=faces.astype(np.int64), process=False)


def normalize(mesh: trimesh.Trimesh, bound: float | None = 0.8) -> tuple[trimesh.Trimesh, np.ndarray, float]:
    """Fit the mesh's bounding box into [-bound, bound]^3: centre it, scale uniformly so its
    longest side spans 2*bound. ``bound=None`` keeps the mesh as it is (centre 0, scale 1): an
    annotation with ``normalize: false`` whose mesh is already in its GCs' frame.

    Returns (new mesh, center (3,) float64, scale float) with
    ``normalised = (original - center) * scale`` and ``original = normalised / scale + center``.
    The input mesh is not modified.
    """
    if bound is None:
        return mesh.copy(), np.zeros(3), 1.0
    if not bound > 0:
        raise DataError(f"normalize bound must be > 0, got {bound}", field="normalize.bound", fix="use e.g. 0.8")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    half = float((hi - lo).max()) / 2.0
    if not half > 0:
        raise DataError(
            "all vertices coincide, the mesh has no extent to normalise",
            fix="give a mesh with a non-degenerate bounding box",
        )
    center = (lo + hi) / 2.0
    scale = float(bound) / half
    out = trimesh.Trimesh(vertices=(vertices - center) * scale, faces=np.asarray(mesh.faces), process=False)
    return out, center, scale
