"""The binary glTF 2.0 writer (pygltflib builds the JSON; the buffer is ours).

One scene: the skinned mesh node and the joint hierarchy at the root. The skin lists the
joints and their inverse bind matrices; the mesh has POSITION, NORMAL, JOINTS_0 (unsigned
short), WEIGHTS_0 (float), optionally COLOR_0, and one morph target per keyframe (named in
`extras.targetNames`, which Blender reads as shape-key names). The clip animates every joint's
rotation and translation and the morph weights (linear). Where a joint turns more than
`max_key_degrees` between two keyframes, the joint channels get in-between keys on the same
slerp (`in_between_keys`): they change nothing for a client that slerps as glTF says, and a
client that interpolates quaternions per component (Blender's fcurves) then plays the same
pose. The keyframes are kept in the animation's `extras.keyframes`. The file is written to a
temp file and renamed: a failure leaves no partial file.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ngc_gen.data.atomic import atomic_write
from ngc_gen.data.rigs.rig import matrix_trs

ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
FLOAT, USHORT, UINT = 5126, 5123, 5125


@dataclass
class GLBContent:
    """Everything a file holds. vertices (V, 3) bind pose, faces (F, 3), normals (V, 3);
    joint names (J,), parent (J,), rest_world (J, 4, 4); skin joints (V, 4) / weights (V, 4);
    clip: name, times (K,), world (K, J, 4, 4); morph: (T, V, 3) bind-space offsets with
    morph_weights (K, T) per keyframe (T = 0: none); colors (V, 4) or None; max_key_degrees:
    the largest turn of a joint between two keys of its channels (`in_between_keys`)."""

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    names: list[str]
    parent: np.ndarray
    rest_world: np.ndarray
    joints: np.ndarray
    weights: np.ndarray
    clip_name: str | None = None
    times: np.ndarray | None = None
    world: np.ndarray | None = None
    morph: np.ndarray | None = None
    morph_weights: np.ndarray | None = None
    morph_names: list[str] = field(default_factory=list)
    colors: np.ndarray | None = None
    name: str = "shape"
    max_key_degrees: float = 180.0


def local_trs(parent: np.ndarray, world: np.ndarray):
    """World matrices (J, 4, 4) -> per joint local (translation (J, 3), rotation (J, 4) x y z w
    with a non-negative w, scale (J, 3))."""
    local = world.copy()
    has = parent >= 0
    local[has] = np.linalg.inv(world[parent[has]]) @ world[has]
    T, R, S = zip(*(matrix_trs(m) for m in local))  # joints (tens)
    R = np.array(R)
    R *= np.where(R[:, 3:] < 0, -1.0, 1.0)
    return np.array(T), R, np.array(S)


class _Buffer:
    def __init__(self, g):
        self.g, self.blob = g, bytearray()

    def add(self, data: np.ndarray, ctype: int, atype: str, target: int | None = None,
            minmax: bool = False) -> int:
        import pygltflib as G

        data = np.ascontiguousarray(data)
        while len(self.blob) % 4:
            self.blob.append(0)
        view = G.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=data.nbytes,
                            target=target)
        self.blob.extend(data.tobytes())
        self.g.bufferViews.append(view)
        count = data.shape[0]
        acc = G.Accessor(bufferView=len(self.g.bufferViews) - 1, componentType=ctype,
                         count=count, type=atype)
        if minmax:
            flat = data.reshape(count, -1)
            acc.min = [float(x) if ctype == FLOAT else int(x) for x in flat.min(0)]
            acc.max = [float(x) if ctype == FLOAT else int(x) for x in flat.max(0)]
        self.g.accessors.append(acc)
        return len(self.g.accessors) - 1


def _mesh(g, buf: _Buffer, c: GLBContent) -> int:
    import pygltflib as G

    f32 = np.float32
    attrs = G.Attributes(
        POSITION=buf.add(c.vertices.astype(f32), FLOAT, "VEC3", ARRAY_BUFFER, True),
        NORMAL=buf.add(c.normals.astype(f32), FLOAT, "VEC3", ARRAY_BUFFER),
        JOINTS_0=buf.add(c.joints.astype(np.uint16), USHORT, "VEC4", ARRAY_BUFFER),
        WEIGHTS_0=buf.add(_normalised_f32(c.weights), FLOAT, "VEC4", ARRAY_BUFFER))
    if c.colors is not None:
        attrs.COLOR_0 = buf.add(c.colors.astype(f32), FLOAT, "VEC4", ARRAY_BUFFER)
    targets = []
    if c.morph is not None and len(c.morph):
        targets = [{"POSITION": buf.add(d.astype(f32), FLOAT, "VEC3", ARRAY_BUFFER, True)}
                   for d in c.morph]
    prim = G.Primitive(attributes=attrs, material=0, mode=4, targets=targets or None,
                       indices=buf.add(c.faces.astype(np.uint32).reshape(-1), UINT, "SCALAR",
                                       ELEMENT_ARRAY_BUFFER, True))
    mesh = G.Mesh(name=c.name, primitives=[prim])
    if targets:
        mesh.weights = [0.0] * len(targets)
        mesh.extras = {"targetNames": list(c.morph_names)}
    g.meshes.append(mesh)
    return len(g.meshes) - 1


def _normalised_f32(w: np.ndarray) -> np.ndarray:
    """Weights as float32 whose rows sum to 1 in float32 (the largest absorbs the rounding)."""
    w = (w / w.sum(1, keepdims=True)).astype(np.float32)
    rest = np.float32(1.0) - (w.sum(1) - w.max(1))
    w[np.arange(len(w)), w.argmax(1)] = rest
    return w


def in_between_keys(times: np.ndarray, T: np.ndarray, R: np.ndarray,
                    max_degrees: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keys (times (K,), translations (K, J, 3), unit quaternions (K, J, 4) on the shorter
    arcs) with in-between keys wherever a joint turns more than `max_degrees` between two:
    the slerp and lerp glTF's LINEAR sampler gives there, so the clip plays the same under
    glTF's rules and near it under per-component interpolation (its error falls as the cube
    of the turn)."""
    times = np.asarray(times, np.float64)
    dot = np.clip(np.abs((R[1:] * R[:-1]).sum(-1)), 0.0, 1.0)  # (K - 1, J)
    turn = np.degrees(2.0 * np.arccos(dot)).max(1)
    n = np.maximum(1, np.ceil(turn / max(float(max_degrees), 1e-6))).astype(np.int64)
    seg = np.repeat(np.arange(len(n)), n)
    f = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
    f = f / n[seg]
    seg, f = np.append(seg, len(n) - 1), np.append(f, 1.0)
    q0, q1 = R[seg], R[seg + 1]
    a = np.arccos(np.clip((q0 * q1).sum(-1, keepdims=True), -1.0, 1.0))  # (N, J, 1)
    s = np.sin(a)
    fb = f[:, None, None]
    near = s < 1e-6  # the same rotation: lerp
    w0 = np.where(near, 1.0 - fb, np.sin((1.0 - fb) * a) / np.where(near, 1.0, s))
    w1 = np.where(near, fb, np.sin(fb * a) / np.where(near, 1.0, s))
    q = w0 * q0 + w1 * q1
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    t = (1.0 - fb) * T[seg] + fb * T[seg + 1]
    return (1.0 - f) * times[seg] + f * times[seg + 1], t, q


def _animation(g, buf: _Buffer, c: GLBContent, mesh_node: int) -> None:
    import pygltflib as G

    keys = buf.add(np.asarray(c.times, np.float32), FLOAT, "SCALAR", None, True)
    T, R = [], []
    for w in c.world:  # keyframes
        t, r, _ = local_trs(c.parent, w)
        T.append(t), R.append(r)
    T, R = np.stack(T), np.stack(R)  # (K, J, 3), (K, J, 4)
    for j in range(1, len(R)):  # the shorter arc between keys: q and -q are one rotation
        R[j] *= np.where((R[j] * R[j - 1]).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    if len(R) > 1:
        dense, T, R = in_between_keys(c.times, T, R, c.max_key_degrees)
        times = buf.add(dense.astype(np.float32), FLOAT, "SCALAR", None, True)
    else:
        times = keys
    samplers, channels = [], []

    def channel(node: int, path: str, values: np.ndarray, atype: str, times=times):
        samplers.append(G.AnimationSampler(input=times, interpolation="LINEAR",
                                           output=buf.add(values.astype(np.float32), FLOAT,
                                                          atype)))
        channels.append(G.AnimationChannel(sampler=len(samplers) - 1,
                                           target=G.AnimationChannelTarget(node=node, path=path)))

    for j in range(len(c.names)):  # joints (tens)
        channel(j, "rotation", R[:, j], "VEC4")
        channel(j, "translation", T[:, j], "VEC3")  # an edit may change a bone's length
    if c.morph is not None and len(c.morph):
        channel(mesh_node, "weights", np.asarray(c.morph_weights).reshape(-1), "SCALAR", keys)
    g.animations.append(G.Animation(name=c.clip_name, samplers=samplers, channels=channels,
                                    extras={"keyframes": [float(x) for x in c.times]}))


def glb_bytes(c: GLBContent) -> bytes:
    """The GLB file of `c`."""
    import pygltflib as G

    g = G.GLTF2(asset=G.Asset(version="2.0", generator="ngc-gen"), scene=0)
    g.bufferViews, g.accessors, g.meshes, g.nodes, g.animations = [], [], [], [], []
    buf = _Buffer(g)
    g.materials = [G.Material(name="default", doubleSided=False,
                              pbrMetallicRoughness=G.PbrMetallicRoughness(
                                  baseColorFactor=[0.8, 0.8, 0.8, 1.0], metallicFactor=0.0,
                                  roughnessFactor=0.7))]
    T, R, _ = local_trs(c.parent, c.rest_world)
    for j, name in enumerate(c.names):  # joints (tens)
        kids = np.flatnonzero(c.parent == j).tolist()
        g.nodes.append(G.Node(name=name, translation=T[j].tolist(), rotation=R[j].tolist(),
                              children=kids or None))
    mesh = _mesh(g, buf, c)
    mesh_node = len(g.nodes)
    ibm = np.linalg.inv(c.rest_world).transpose(0, 2, 1)  # column-major
    g.skins = [G.Skin(name="skeleton", joints=list(range(len(c.names))),
                      skeleton=int(np.flatnonzero(c.parent < 0)[0]),
                      inverseBindMatrices=buf.add(ibm.reshape(-1, 16).astype(np.float32), FLOAT,
                                                  "MAT4"))]
    g.nodes.append(G.Node(name=c.name, mesh=mesh, skin=0))
    if c.times is not None:
        _animation(g, buf, c, mesh_node)
    roots = np.flatnonzero(c.parent < 0).tolist()
    g.scenes = [G.Scene(name=c.name, nodes=[mesh_node] + roots)]
    if not g.animations:
        g.animations = None
    g.buffers = [G.Buffer(byteLength=len(buf.blob))]
    g.set_binary_blob(bytes(buf.blob))
    return b"".join(g.save_to_bytes())


def write_glb(path: str | os.PathLike, c: GLBContent) -> int:
    """Write `c` to `path` atomically; returns the byte count."""
    data = glb_bytes(c)
    atomic_write(path, lambda f: f.write(data))
    return len(data)
