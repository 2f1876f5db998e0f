"""What a glTF (.gltf + its buffers) or GLB file says before trimesh reads it: the JSON parses,
every index it holds (buffer, view, accessor, mesh, node) points at something that exists, the
buffer files exist and are long enough, the node tree has no circle, some primitive is made of
triangles, the positions are finite and the triangle indices are below the vertex count.

The standard library reads the JSON; numpy (no trimesh, no torch) reads the positions and
indices, so `train.py` refuses a malformed file in a second with the words `load_mesh` uses.
What this does not know (extensions such as Draco, sparse accessors) is left to `load_mesh`.
"""
from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

from ngc_gen.data.errors import DataError

READ_FIX = "re-export the mesh from the program that made it (a complete glTF 2.0 / GLB file)"
NO_TRIANGLES_FIX = "give a surface mesh with faces; point clouds and empty files cannot be prepared"
NAN_FIX = "repair or re-export the mesh so every vertex coordinate is a finite number"
INDEX_FIX = "re-export the mesh; its faces refer to vertices that do not exist"

# accessor componentType -> numpy type code; accessor type -> components per element
COMPONENT = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
TRIANGLE_MODES = (None, 4, 5, 6)  # TRIANGLES (the default), TRIANGLE_STRIP, TRIANGLE_FAN


def _bad(what: str, path: Path, fix: str = READ_FIX) -> DataError:
    return DataError(what, path=path, fix=fix)


def _json(text: bytes, path: Path) -> dict:
    try:
        doc = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        where = f" (line {e.lineno}, column {e.colno})" if hasattr(e, "lineno") else ""
        raise _bad(f"its glTF JSON does not parse{where}: {str(e).split(':')[0]}", path) \
            from None
    if not isinstance(doc, dict):
        raise _bad("its glTF JSON is not an object", path)
    return doc


def _glb(path: Path) -> tuple[dict, bytes | None]:
    """(JSON, BIN chunk or None) of a GLB file."""
    data = path.read_bytes()
    if len(data) < 20 or data[:4] != b"glTF":
        raise _bad("not a GLB file (no glTF header)", path)
    _, length = struct.unpack_from("<II", data, 4)
    if length > len(data):
        raise _bad(f"the file ends early (its GLB header declares {length} bytes, the file "
                   f"has {len(data)})", path)
    size, kind = struct.unpack_from("<II", data, 12)
    if kind != 0x4E4F534A or 20 + size > length:  # "JSON"
        raise _bad("its GLB JSON chunk is missing or longer than the file", path)
    doc = _json(data[20:20 + size], path)
    at = 20 + size + (-size % 4)
    if at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        if kind == 0x004E4942:  # "BIN\0"
            if at + 8 + size > length:
                raise _bad("its GLB BIN chunk is longer than the file", path)
            return doc, data[at + 8:at + 8 + size]
    return doc, None


def _list(doc: dict, key: str, path: Path) -> list:
    items = doc.get(key, [])
    if not isinstance(items, list) or not all(isinstance(x, dict) for x in items):
        raise _bad(f"its glTF '{key}' is not a list of objects", path)
    return items


def _index(value, items: list, what: str, path: Path) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < len(items):
        raise _bad(f"its glTF {what} = {value!r} is out of range (there are {len(items)})",
                   path)
    return value


def _buffers(doc: dict, path: Path, bin_chunk: bytes | None) -> list[bytes | None]:
    """Each buffer's bytes (None where they are not read: a buffer no accessor needs is still
    checked for existence and length)."""
    out = []
    for i, b in enumerate(_list(doc, "buffers", path)):
        uri, length = b.get("uri"), b.get("byteLength", 0)
        if uri is None:
            if i != 0 or bin_chunk is None:
                raise _bad(f"its glTF buffer {i} has no uri and no GLB BIN chunk", path)
            data = bin_chunk
        elif uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.split(",", 1)[1], validate=True)
            except (IndexError, ValueError):
                raise _bad(f"its glTF buffer {i} data URI is not base64", path) from None
        else:
            file = path.parent / uri
            if not file.is_file():
                raise _bad(f"its glTF buffer {i} file '{uri}' is missing", path,
                           fix=f"put {uri} beside {path.name}, or export a single .glb file")
            data = file.read_bytes()
        if not isinstance(length, int) or len(data) < length:
            raise _bad(f"its glTF buffer {i} holds {len(data)} bytes, fewer than its byteLength "
                       f"{length}", path)
        out.append(data)
    return out


def _check_views(doc: dict, path: Path, buffers: list) -> list[dict]:
    views = _list(doc, "bufferViews", path)
    for i, v in enumerate(views):
        b = _index(v.get("buffer"), buffers, f"bufferViews[{i}].buffer", path)
        end = v.get("byteOffset", 0) + v.get("byteLength", 0)
        if end > len(buffers[b]):
            raise _bad(f"its glTF bufferView {i} ends at byte {end}, past its buffer's "
                       f"{len(buffers[b])}", path)
    return views


def _read(doc: dict, k: int, path: Path, buffers: list, views: list):
    """Accessor k as a numpy array (count, width), or None where it has no plain data."""
    import numpy as np

    a = doc["accessors"][k]
    if "bufferView" not in a or "sparse" in a or a.get("componentType") not in COMPONENT \
            or a.get("type") not in WIDTH:
        return None
    v = views[_index(a["bufferView"], views, f"accessors[{k}].bufferView", path)]
    dtype = np.dtype(COMPONENT[a["componentType"]])
    width, count = WIDTH[a["type"]], int(a.get("count", 0))
    stride = v.get("byteStride") or dtype.itemsize * width
    start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    need = stride * max(count - 1, 0) + dtype.itemsize * width if count else 0
    if start - v.get("byteOffset", 0) + need > v.get("byteLength", 0):
        raise _bad(f"its glTF accessor {k} ({count} x {a['type']}) runs past its bufferView",
                   path)
    raw = np.frombuffer(buffers[v["buffer"]], dtype=np.uint8, count=need, offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, (count, dtype.itemsize * width), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(count, width)


def _check_nodes(doc: dict, path: Path) -> None:
    """Node and scene indices exist and no node is its own descendant (a circle)."""
    nodes, meshes = _list(doc, "nodes", path), doc.get("meshes", [])
    for i, n in enumerate(nodes):
        for c in n.get("children", []):
            _index(c, nodes, f"nodes[{i}].children", path)
        if "mesh" in n:
            _index(n["mesh"], meshes, f"nodes[{i}].mesh", path)
    for s, scene in enumerate(_list(doc, "scenes", path)):
        for n in scene.get("nodes", []):
            _index(n, nodes, f"scenes[{s}].nodes", path)
    state = [0] * len(nodes)  # 0 unseen, 1 on the current path, 2 done
    for root in range(len(nodes)):
        stack = [(root, iter(nodes[root].get("children", [])))] if not state[root] else []
        state[root] = state[root] or 1
        while stack:
            node, children = stack[-1]
            child = next(children, None)
            if child is None:
                state[node] = 2
                stack.pop()
            elif state[child] == 1:
                raise _bad(f"its glTF node {child} is its own descendant (the node tree has a "
                           f"circle)", path)
            elif state[child] == 0:
                state[child] = 1
                stack.append((child, iter(nodes[child].get("children", []))))


def _check_primitive(doc, m: int, j: int, prim: dict, path: Path, buffers, views) -> bool:
    """Checks one primitive; True if it is made of triangles."""
    import numpy as np

    accessors = doc.get("accessors", [])
    where = f"meshes[{m}].primitives[{j}]"
    attributes = prim.get("attributes")
    if not isinstance(attributes, dict) or "POSITION" not in attributes:
        raise _bad(f"its glTF {where} has no POSITION attribute", path)
    for name, k in attributes.items():
        _index(k, accessors, f"{where}.attributes.{name}", path)
    pos = _read(doc, attributes["POSITION"], path, buffers, views)
    n_vertices = int(accessors[attributes["POSITION"]].get("count", 0))
    if pos is not None:
        bad = ~np.isfinite(pos).all(axis=1)
        if bad.any():
            raise _bad(f"{int(bad.sum())} of {len(pos)} vertices are NaN or infinite (first: "
                       f"vertex {int(np.argmax(bad))})", path, fix=NAN_FIX)
    if "indices" in prim:
        idx = _read(doc, _index(prim["indices"], accessors, f"{where}.indices", path), path,
                    buffers, views)
        if idx is not None and len(idx) and int(idx.max()) >= n_vertices:
            raise _bad(f"face indices span [{int(idx.min())}, {int(idx.max())}] but the mesh "
                       f"has {n_vertices} vertices", path, fix=INDEX_FIX)
    return prim.get("mode") in TRIANGLE_MODES


def check_gltf_file(path: Path) -> None:
    """DataError if the glTF or GLB file at `path` is malformed in a way its JSON, its buffers
    and its positions and indices show (see the module docstring)."""
    if path.suffix.lower() == ".glb":
        doc, bin_chunk = _glb(path)
    else:
        doc, bin_chunk = _json(path.read_bytes(), path), None
    buffers = _buffers(doc, path, bin_chunk)
    views = _check_views(doc, path, buffers)
    _list(doc, "accessors", path)
    _check_nodes(doc, path)
    triangles = False
    for m, mesh in enumerate(_list(doc, "meshes", path)):
        for j, prim in enumerate(mesh.get("primitives", [])):
            if not isinstance(prim, dict):
                raise _bad(f"its glTF meshes[{m}].primitives[{j}] is not an object", path)
            triangles |= _check_primitive(doc, m, j, prim, path, buffers, views)
    if not triangles:
        raise _bad("the file holds no triangles (no glTF mesh primitive of triangles)", path,
                   fix=NO_TRIANGLES_FIX)
