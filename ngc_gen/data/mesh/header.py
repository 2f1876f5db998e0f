"""What a mesh file's header (and, for text files, its lines) tells without reading the mesh:
a missing file, a PLY that declares no faces, an OBJ without `f` lines, NaN or infinite
coordinates in a text file. Standard library only: `train.py` checks its meshes with it before
numpy, trimesh and torch load, so a bad mesh fails in a second; `load_mesh` checks the rest
when the mesh is read (same words, same fixes).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from ngc_gen.data.errors import DataError

TEXT_SCAN_BYTES = 64 << 20  # text meshes up to this size are scanned for NaN coordinates
NO_TRIANGLES_FIX = "give a surface mesh with faces; point clouds and empty files cannot be prepared"
NAN_FIX = "repair or re-export the mesh so every vertex coordinate is a finite number"
MISSING_FIX = "check the path (relative paths in an annotation are relative to the YAML file)"


def _finite(words) -> bool:
    try:
        return all(math.isfinite(float(w)) for w in words)
    except ValueError:
        return True  # not a number at all: trimesh's reader reports it


def _ply(path: Path) -> None:
    with open(path, "rb") as f:
        head = f.read(1 << 16)
    if not head.startswith(b"ply"):
        return  # not a PLY after all: trimesh says what it is
    end = head.find(b"end_header")
    if end < 0:
        return
    lines = head[:end].decode("ascii", "replace").splitlines()
    ascii_ = any(ln.split()[:2] == ["format", "ascii"] for ln in lines if ln.strip())
    counts = {}
    for ln in lines:
        w = ln.split()
        if len(w) == 3 and w[0] == "element":
            counts[w[1]] = int(w[2]) if w[2].isdigit() else -1
    if counts.get("face", 0) == 0:
        raise DataError("the file holds no triangles (its PLY header declares no faces)",
                        path=path, fix=NO_TRIANGLES_FIX)
    if ascii_ and path.stat().st_size <= TEXT_SCAN_BYTES and list(counts)[:1] == ["vertex"]:
        body = path.read_bytes()[head.find(b"\n", end) + 1:].decode("ascii", "replace")
        rows = body.splitlines()[:counts["vertex"]]
        bad = [i for i, row in enumerate(rows) if not _finite(row.split()[:3])]
        if bad:
            raise DataError(f"{len(bad)} of {len(rows)} vertices are NaN or infinite (first: "
                            f"vertex {bad[0]})", path=path, fix=NAN_FIX)


def _obj(path: Path) -> None:
    if path.stat().st_size > TEXT_SCAN_BYTES:
        return
    faces, bad, n = False, [], 0
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("f "):
                faces = True
            elif line.startswith("v "):
                if not _finite(line.split()[1:4]):
                    bad.append(n)
                n += 1
    if not faces:
        raise DataError("the file holds no triangles (no `f` lines in the OBJ)", path=path,
                        fix=NO_TRIANGLES_FIX)
    if bad:
        raise DataError(f"{len(bad)} of {n} vertices are NaN or infinite (first: vertex "
                        f"{bad[0]})", path=path, fix=NAN_FIX)


def check_mesh_file(path: str | os.PathLike) -> Path:
    """DataError if the mesh file is missing, empty, declares no triangles or (text formats)
    holds non-finite coordinates; what a header cannot tell is left to `load_mesh`."""
    path = Path(path)
    if not path.is_file():
        raise DataError("mesh file not found" if not path.exists() else "mesh path is not a file",
                        path=path, fix=MISSING_FIX)
    if path.stat().st_size == 0:
        raise DataError("the file holds no triangles (it is empty)", path=path,
                        fix=NO_TRIANGLES_FIX)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        _ply(path)
    elif suffix == ".obj":
        _obj(path)
    return path
