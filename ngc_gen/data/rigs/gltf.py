"""Read a skinned glTF 2.0 / GLB file into a `Rig` (`gltf_json.read_gltf` reads the JSON and
buffers).

What is read: every node (name, parent, rest translation / rotation / scale, or a matrix), the
first skin (joints, inverse bind matrices), every mesh primitive of the nodes that use that skin
(POSITION, indices, JOINTS_0, WEIGHTS_0; triangles only), concatenated, and every animation
(channels of translation / rotation / scale with their samplers). Morph targets and other
skins are ignored. Anything malformed is a DataError naming the file and what is missing.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ngc_gen.data.errors import DataError

from .gltf_json import read_gltf
from .rig import INTERPOLATIONS, PATHS, Channel, Clip, Rig, matrix_trs

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
               5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_NORM = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
_FIX = "re-export the rig as a glTF 2.0 binary (.glb) with its skin and animations"


class _Reader:
    def __init__(self, gltf, source: str):
        self.g, self.source = gltf, source
        self.blob = gltf.binary_blob()
        self.buffers: dict[int, bytes] = {}

    def fail(self, what: str, field: str | None = None):
        raise DataError(what, path=self.source, field=field, fix=_FIX)

    def buffer(self, index: int) -> bytes:
        if index not in self.buffers:
            buf = self.g.buffers[index]
            if buf.uri is None:
                if self.blob is None:
                    self.fail(f"buffer {index} has no data (no binary chunk)", f"buffers[{index}]")
                self.buffers[index] = self.blob
            else:
                try:
                    self.buffers[index] = self.g.get_data_from_buffer_uri(buf.uri)
                except Exception as e:  # a data: URI or a file beside the .gltf
                    path = Path(self.source).parent / buf.uri
                    if not path.is_file():
                        self.fail(f"buffer {index}: cannot read {buf.uri!r} ({type(e).__name__})",
                                  f"buffers[{index}].uri")
                    self.buffers[index] = path.read_bytes()
        return self.buffers[index]

    def accessor(self, index: int | None, what: str) -> np.ndarray:
        """Accessor `index` as an (count, width) float64 or int array (normalised ints scaled)."""
        if index is None or not 0 <= index < len(self.g.accessors):
            self.fail(f"{what}: accessor {index} does not exist", f"accessors[{index}]")
        acc = self.g.accessors[index]
        dtype = _COMPONENTS.get(acc.componentType)
        width = _WIDTH.get(acc.type)
        if dtype is None or width is None:
            self.fail(f"{what}: unsupported accessor type {acc.type}/{acc.componentType}",
                      f"accessors[{index}]")
        if acc.bufferView is None:
            out = np.zeros((acc.count, width), dtype)
        else:
            view = self.g.bufferViews[acc.bufferView]
            data = self.buffer(view.buffer)
            start = (view.byteOffset or 0) + (acc.byteOffset or 0)
            item = np.dtype(dtype).itemsize * width
            stride = view.byteStride or item
            end = start + stride * (acc.count - 1) + item
            if acc.count and end > min(len(data), (view.byteOffset or 0) + view.byteLength):
                self.fail(f"{what}: accessor {index} reads past the end of its buffer "
                          f"({end} > {len(data)} bytes); the file is truncated",
                          f"accessors[{index}]")
            raw = np.frombuffer(data, np.uint8, count=max(end - start, 0), offset=start)
            if stride == item:
                out = raw.view(dtype).reshape(acc.count, width).copy()
            else:
                rows = np.lib.stride_tricks.as_strided(raw, (acc.count, item), (stride, 1))
                out = np.ascontiguousarray(rows).view(dtype).reshape(acc.count, width)
        if acc.sparse is not None:
            self.fail(f"{what}: sparse accessors are not supported", f"accessors[{index}]")
        if acc.normalized and acc.componentType in _NORM:
            return np.maximum(out.astype(np.float64) / _NORM[acc.componentType], -1.0)
        return out.astype(np.float64) if dtype == np.float32 else out.astype(np.int64)


def load_gltf_rig(path: str | os.PathLike) -> Rig:
    """The rig of a .glb / .gltf file (DataError naming the file for anything missing)."""
    path = Path(path)
    source = os.fspath(path)
    if not path.is_file():
        raise DataError("rig file not found", path=source, fix="check the path")
    try:
        g = read_gltf(source)
    except Exception as e:  # json, struct and unicode errors on a bad file
        raise DataError(f"could not read the glTF ({type(e).__name__}: {str(e)[:120]})",
                        path=source, fix=_FIX) from None
    if g is None or not g.nodes:
        raise DataError("not a glTF file with nodes (malformed or empty)", path=source, fix=_FIX)
    r = _Reader(g, source)
    if not g.skins:
        r.fail("the file has no skin (no joints and weights)", "skins")
    names = [nd.name or f"node_{i}" for i, nd in enumerate(g.nodes)]
    parent = _parents(g, r, names)
    T, R, S = _node_trs(g)
    joints, ibm = _skin_joints(g, r)
    V, F, J, W = _skinned_primitives(g, r, names, len(joints))
    weights = np.concatenate(W)
    total = weights.sum(1, keepdims=True)
    if (total <= 0).any():
        r.fail(f"{int((total <= 0).sum())} vertices have no skin weight", "WEIGHTS_0")
    return Rig(names=names, parent=parent, translation=T, rotation=R, scale=S, joints=joints,
               inverse_bind=ibm, vertices=np.concatenate(V), faces=np.concatenate(F),
               skin_joints=np.concatenate(J), skin_weights=weights / total,
               clips=_clips(g, r, names), source=source)


def _parents(g, r: _Reader, names: list[str]) -> np.ndarray:
    """(n,) each node's parent index, -1 for a root; a child listed twice or missing fails."""
    n = len(g.nodes)
    parent = np.full(n, -1)
    for i, nd in enumerate(g.nodes):
        for c in nd.children or []:
            if not 0 <= c < n or parent[c] >= 0:
                r.fail(f"node {names[i]!r} lists child {c}, which is missing or has two parents",
                       f"nodes[{i}].children")
            parent[c] = i
    return parent


def _node_trs(g) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nodes' local translation (n, 3), rotation quaternion xyzw (n, 4) and scale (n, 3)."""
    n = len(g.nodes)
    T, R, S = np.zeros((n, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), np.ones((n, 3))
    for i, nd in enumerate(g.nodes):
        if nd.matrix is not None:
            T[i], R[i], S[i] = matrix_trs(np.asarray(nd.matrix, np.float64).reshape(4, 4).T)
            continue
        if nd.translation is not None:
            T[i] = nd.translation
        if nd.rotation is not None:
            R[i] = nd.rotation
        if nd.scale is not None:
            S[i] = nd.scale
    return T, R, S


def _skin_joints(g, r: _Reader) -> tuple[np.ndarray, np.ndarray]:
    """The first skin's joint nodes (J,) and inverse bind matrices (J, 4, 4), row-major."""
    skin = g.skins[0]
    joints = np.asarray(skin.joints or [], np.int64)
    if len(joints) == 0 or joints.min() < 0 or joints.max() >= len(g.nodes):
        r.fail("the skin's joint list is empty or names nodes that do not exist", "skins[0].joints")
    if skin.inverseBindMatrices is None:
        return joints, np.tile(np.eye(4), (len(joints), 1, 1))
    m = r.accessor(skin.inverseBindMatrices, "inverse bind matrices")
    if len(m) != len(joints):
        r.fail(f"{len(m)} inverse bind matrices for {len(joints)} joints",
               "skins[0].inverseBindMatrices")
    return joints, m.reshape(-1, 4, 4).transpose(0, 2, 1)  # glTF matrices are column-major


def _skinned_primitives(g, r: _Reader, names: list[str], n_joints: int) -> tuple[list, ...]:
    """Lists of vertices, faces (offset into one mesh), joints and weights of every triangle
    primitive of a node bound to the first skin."""
    V, F, J, W = [], [], [], []
    offset = 0
    for i, nd in enumerate(g.nodes):
        if nd.mesh is None or nd.skin != 0:
            continue
        for k, prim in enumerate(g.meshes[nd.mesh].primitives):
            where = f"meshes[{nd.mesh}].primitives[{k}]"
            if prim.mode not in (None, 4):
                continue  # lines and points carry no surface
            a = prim.attributes
            if a.POSITION is None or a.JOINTS_0 is None or a.WEIGHTS_0 is None:
                r.fail(f"primitive of mesh {names[i]!r} lacks POSITION, JOINTS_0 or WEIGHTS_0",
                       where + ".attributes")
            pos = r.accessor(a.POSITION, f"{where} POSITION")
            idx = (r.accessor(prim.indices, f"{where} indices").reshape(-1, 3)
                   if prim.indices is not None else np.arange(len(pos)).reshape(-1, 3))
            jj = r.accessor(a.JOINTS_0, f"{where} JOINTS_0")
            ww = r.accessor(a.WEIGHTS_0, f"{where} WEIGHTS_0")
            if not (len(jj) == len(ww) == len(pos)) or jj.shape[1] != 4 or ww.shape[1] != 4:
                r.fail("JOINTS_0 / WEIGHTS_0 do not match POSITION (4 per vertex)", where)
            if idx.size and (idx.min() < 0 or idx.max() >= len(pos)):
                r.fail("triangle indices out of range", where + ".indices")
            if jj.max() >= n_joints or jj.min() < 0:
                r.fail(f"JOINTS_0 names joint {int(jj.max())}, the skin has {n_joints}", where)
            V.append(pos), F.append(idx + offset), J.append(jj), W.append(ww)
            offset += len(pos)
    if not V:
        r.fail("no triangle mesh uses the skin", "nodes[*].skin")
    return V, F, J, W


def _clips(g, r: _Reader, names: list[str]) -> dict[str, Clip]:
    """The file's animations as clips of joint TRS channels (morph weights are skipped)."""
    clips = {}
    for k, anim in enumerate(g.animations or []):
        name = anim.name or f"clip_{k}"
        chans = []
        for c in anim.channels:
            if c.target is None or c.target.node is None or c.target.path not in PATHS:
                continue  # morph-target weights and pointer channels do not move joints
            if not 0 <= c.sampler < len(anim.samplers):
                r.fail(f"clip {name!r}: channel uses missing sampler {c.sampler}",
                       f"animations[{k}].channels")
            s = anim.samplers[c.sampler]
            interp = s.interpolation or "LINEAR"
            if interp not in INTERPOLATIONS:
                r.fail(f"clip {name!r}: unknown interpolation {interp!r}", f"animations[{k}]")
            times = r.accessor(s.input, f"clip {name!r} times").ravel().astype(np.float64)
            values = r.accessor(s.output, f"clip {name!r} values").astype(np.float64)
            want = len(times) * (3 if interp == "CUBICSPLINE" else 1)
            if len(values) != want or not len(times) or (np.diff(times) < 0).any():
                r.fail(f"clip {name!r}: sampler of node {names[c.target.node]!r} has "
                       f"{len(values)} values for {len(times)} times", f"animations[{k}]")
            chans.append(Channel(int(c.target.node), c.target.path, times, values, interp))
        clips[name] = Clip(name, tuple(chans))
    return clips
