"""What a mesh file says before trimesh reads it: a missing or empty file, a header that declares
no faces, a file that ends before the data its header declares, NaN or infinite coordinates,
face indices past the vertex count, and for glTF / GLB their JSON and buffers
(`gltf_header`). PLY, OBJ, OFF, STL, glTF and GLB are read with the standard library and numpy
only: `train.py` checks its meshes with this before trimesh and torch load, so a malformed file
fails in a second; `load_mesh` checks the rest when the mesh is read (same words, same fixes).
"""
from __future__ import annotations

import math
import os
import struct
from pathlib import Path

from ngc_gen.data.errors import DataError

from .gltf_header import INDEX_FIX, NAN_FIX, NO_TRIANGLES_FIX, READ_FIX, check_gltf_file

TEXT_SCAN_BYTES = 64 << 20  # text meshes up to this size are scanned row by row
MISSING_FIX = "check the path (relative paths in an annotation are relative to the YAML file)"
# PLY property type -> numpy type code (the byte order is added from the header's format)
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
             "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
             "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
             "float64": "f8"}


def _finite(words) -> bool:
    try:
        return all(math.isfinite(float(w)) for w in words)
    except ValueError:
        return True  # not a number at all: trimesh's reader reports it


def _non_finite(rows: list[list[str]], path: Path) -> None:
    """DataError naming the rows whose first three words are not finite numbers."""
    bad = [i for i, row in enumerate(rows) if not _finite(row[:3])]
    if bad:
        raise DataError(f"{len(bad)} of {len(rows)} vertices are NaN or infinite (first: "
                        f"vertex {bad[0]})", path=path, fix=NAN_FIX)


def _index_range(faces: list[list[int]], n_vertices: int, path: Path) -> None:
    lo = min((min(f) for f in faces if f), default=0)
    hi = max((max(f) for f in faces if f), default=0)
    if lo < 0 or hi >= n_vertices:
        raise DataError(f"face indices span [{lo}, {hi}] but the mesh has {n_vertices} "
                        "vertices", path=path, fix=INDEX_FIX)


def _ends_early(what: str, path: Path) -> DataError:
    return DataError(f"the file ends early ({what})", path=path, fix=READ_FIX)


def _ply_header(head: bytes) -> tuple[str, list[tuple[str, int, list[list[str]]]], int] | None:
    """(format, [(element, count, [property words])], bytes before the data), or None."""
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return None
    fmt, elements = "ascii", []
    for line in head[:end].decode("ascii", "replace").splitlines():
        w = line.split()
        if w[:1] == ["format"] and len(w) > 1:
            fmt = w[1]
        elif w[:1] == ["element"] and len(w) == 3:
            elements.append((w[1], int(w[2]) if w[2].isdigit() else -1, []))
        elif w[:1] == ["property"] and elements:
            elements[-1][2].append(w[1:])
    return fmt, elements, head.find(b"\n", end) + 1


def _ply_ascii(path: Path, data_at: int, elements: list) -> None:
    if path.stat().st_size > TEXT_SCAN_BYTES:
        return
    rows = [r.split() for r in path.read_bytes()[data_at:].decode("ascii", "replace")
            .splitlines() if r.strip()]
    counts = {name: n for name, n, _ in elements}
    if len(rows) < sum(counts.values()):
        declared = " and ".join(f"{n} {e}s" for e, n in counts.items())
        raise _ends_early(f"its PLY header declares {declared}, the file holds {len(rows)} "
                          "rows", path)
    if list(counts)[:1] != ["vertex"]:
        return
    nv = counts["vertex"]
    _non_finite(rows[:nv], path)
    if list(counts)[1:2] == ["face"]:
        try:
            faces = [[int(i) for i in r[1:1 + int(r[0])]] for r in rows[nv:nv + counts["face"]]]
        except ValueError:
            return  # trimesh's reader says what is wrong
        _index_range(faces, nv, path)


def _ply_binary(path: Path, fmt: str, elements: list, data_at: int) -> None:
    import numpy as np

    order = "<" if fmt == "binary_little_endian" else ">"
    names = [e[0] for e in elements]
    if names[:2] != ["vertex", "face"] or any(p[0] == "list" for p in elements[0][2]):
        return
    (_, nv, vprops), (_, nf, fprops) = elements[0], elements[1]
    if any(p[0] not in PLY_TYPES for p in vprops) or len(fprops) != 1 \
            or fprops[0][0] != "list" or fprops[0][1] not in PLY_TYPES \
            or fprops[0][2] not in PLY_TYPES:
        return
    vdtype = np.dtype([(p[1], order + PLY_TYPES[p[0]]) for p in vprops])
    fdtype = np.dtype([("n", order + PLY_TYPES[fprops[0][1]]),
                       ("i", order + PLY_TYPES[fprops[0][2]], 3)])
    data = path.read_bytes()
    need = data_at + nv * vdtype.itemsize + nf * fdtype.itemsize  # every face a triangle
    if len(data) < need:
        raise _ends_early(f"its PLY header declares {nv} vertices and {nf} faces: at least "
                          f"{need} bytes, the file has {len(data)}", path)
    v = np.frombuffer(data, vdtype, nv, data_at)
    xyz = [v[k].astype(np.float64) for k in ("x", "y", "z") if k in vdtype.names]
    bad = ~np.isfinite(np.stack(xyz, 1)).all(axis=1) if xyz else np.zeros(0, bool)
    if bad.any():
        raise DataError(f"{int(bad.sum())} of {nv} vertices are NaN or infinite (first: vertex "
                        f"{int(np.argmax(bad))})", path=path, fix=NAN_FIX)
    f = np.frombuffer(data, fdtype, nf, data_at + nv * vdtype.itemsize)
    if nf and (f["n"] == 3).all():  # all triangles: the records are read as they are
        lo, hi = int(f["i"].min()), int(f["i"].max())
        if lo < 0 or hi >= nv:
            raise DataError(f"face indices span [{lo}, {hi}] but the mesh has {nv} vertices",
                            path=path, fix=INDEX_FIX)


def _ply(path: Path) -> None:
    with open(path, "rb") as f:
        head = f.read(1 << 16)
    parsed = _ply_header(head)
    if parsed is None:
        return  # not a PLY after all (or a header past 64 kB): trimesh says what it is
    fmt, elements, data_at = parsed
    counts = {name: n for name, n, _ in elements}
    if counts.get("face", 0) == 0:
        raise DataError("the file holds no triangles (its PLY header declares no faces)",
                        path=path, fix=NO_TRIANGLES_FIX)
    if fmt == "ascii":
        _ply_ascii(path, data_at, elements)
    elif fmt in ("binary_little_endian", "binary_big_endian"):
        _ply_binary(path, fmt, elements, data_at)


def _obj(path: Path) -> None:
    if path.stat().st_size > TEXT_SCAN_BYTES:
        return
    vertices, faces = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("v "):
                vertices.append(line.split()[1:4])
            elif line.startswith("f "):
                faces.append(line.split()[1:])
    if not faces:
        raise DataError("the file holds no triangles (no `f` lines in the OBJ)", path=path,
                        fix=NO_TRIANGLES_FIX)
    _non_finite(vertices, path)
    try:  # 1-based, negative: relative to the vertices read so far (only checked when positive)
        index = [[int(w.split("/")[0]) - 1 for w in face] for face in faces]
    except ValueError:
        return
    if all(i >= 0 for face in index for i in face):
        _index_range(index, len(vertices), path)


def _off(path: Path) -> None:
    if path.stat().st_size > TEXT_SCAN_BYTES:
        return
    text = path.read_text(encoding="utf-8", errors="replace")
    rows = [r.split("#")[0].split() for r in text.splitlines()]
    rows = [r for r in rows if r]
    if not rows or not rows[0][0].endswith("OFF"):
        return  # not an OFF after all: trimesh says what it is
    head = rows[0][1:] or (rows[1] if len(rows) > 1 else [])
    body = rows[1:] if rows[0][1:] else rows[2:]
    try:
        nv, nf = int(head[0]), int(head[1])
    except (IndexError, ValueError):
        raise DataError("its OFF header has no vertex and face counts", path=path,
                        fix=READ_FIX) from None
    if nf == 0:
        raise DataError("the file holds no triangles (its OFF header declares no faces)",
                        path=path, fix=NO_TRIANGLES_FIX)
    if len(body) < nv + nf:
        raise _ends_early(f"its OFF header declares {nv} vertices and {nf} faces, the file "
                          f"holds {len(body)} rows", path)
    _non_finite(body[:nv], path)
    try:
        faces = [[int(i) for i in r[1:1 + int(r[0])]] for r in body[nv:nv + nf]]
    except ValueError:
        return
    _index_range(faces, nv, path)


def _stl(path: Path) -> None:
    import numpy as np

    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
    n = struct.unpack_from("<I", head, 80)[0] if len(head) == 84 else -1
    if n >= 0 and size == 84 + 50 * n:  # binary
        if n == 0:
            raise DataError("the file holds no triangles (its STL header declares none)",
                            path=path, fix=NO_TRIANGLES_FIX)
        tri = np.frombuffer(path.read_bytes(), np.dtype([("normal", "<f4", 3),
                                                         ("v", "<f4", (3, 3)),
                                                         ("attr", "<u2")]), n, 84)
        bad = ~np.isfinite(tri["v"].reshape(-1, 3)).all(axis=1)
        if bad.any():
            raise DataError(f"{int(bad.sum())} of {3 * n} vertices are NaN or infinite "
                            f"(first: vertex {int(np.argmax(bad))})", path=path, fix=NAN_FIX)
    elif head.lstrip().startswith(b"solid") and size <= TEXT_SCAN_BYTES \
            and b"\0" not in path.read_bytes()[:4096]:  # ASCII
        text = path.read_text(encoding="utf-8", errors="replace")
        if "facet" not in text:
            raise DataError("the file holds no triangles (no `facet` in the ASCII STL)",
                            path=path, fix=NO_TRIANGLES_FIX)
        _non_finite([r.split()[1:4] for r in text.splitlines()
                     if r.lstrip().startswith("vertex")], path)
    elif n >= 0 and size < 84 + 50 * n:
        raise _ends_early(f"its STL header declares {n} triangles: {84 + 50 * n} bytes, the "
                          f"file has {size}", path)


CHECKS = {".ply": _ply, ".obj": _obj, ".off": _off, ".stl": _stl, ".gltf": check_gltf_file,
          ".glb": check_gltf_file}


def check_mesh_file(path: str | os.PathLike) -> Path:
    """DataError if the mesh file is missing, empty, or malformed in a way its header and data
    show (the module docstring); what they cannot tell is left to `load_mesh`."""
    path = Path(path)
    if not path.is_file():
        raise DataError("mesh file not found" if not path.exists() else "mesh path is not a file",
                        path=path, fix=MISSING_FIX)
    if path.stat().st_size == 0:
        raise DataError("the file holds no triangles (it is empty)", path=path,
                        fix=NO_TRIANGLES_FIX)
    check = CHECKS.get(path.suffix.lower())
    if check is not None:
        check(path)
    return path
