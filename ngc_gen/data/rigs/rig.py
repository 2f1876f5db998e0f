"""A rig: a node graph with rest transforms, a skinned mesh and animation clips, posed by
linear blend skinning.

    v' = sum_j w_j  T_j  B_j^-1  v

T_j is joint j's world matrix at the pose (the product of the local transforms from the root),
B_j^-1 its inverse bind matrix. Every node has a rest transform (translation, rotation as a
unit quaternion x y z w, scale, as glTF stores them); a clip's channels replace one of those
three fields of one node by a sampled curve over time. Posing loops over nodes (tens), never
over vertices: the vertices are one einsum.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ngc_gen.data.errors import DataError

PATHS = ("translation", "rotation", "scale")
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")


@dataclass(frozen=True)
class Channel:
    """One animated field of one node: `times` (K,) ascending seconds; `values` (K, C) (C = 3
    for translation and scale, 4 for a rotation quaternion x y z w), or (3K, C) for CUBICSPLINE
    (in-tangent, value, out-tangent per key, as glTF stores them)."""

    node: int
    path: str
    times: np.ndarray
    values: np.ndarray
    interpolation: str = "LINEAR"


@dataclass(frozen=True)
class Clip:
    """A named animation: its channels; time runs over [start, end] seconds."""

    name: str
    channels: tuple[Channel, ...]

    @property
    def start(self) -> float:
        return float(min(c.times[0] for c in self.channels)) if self.channels else 0.0

    @property
    def end(self) -> float:
        return float(max(c.times[-1] for c in self.channels)) if self.channels else 0.0

    @property
    def duration(self) -> float:
        return self.end - self.start


@dataclass
class Rig:
    """Nodes (joints and the nodes above them), the skin and the clips of one rigged mesh.

    names (N,), parent (N,) int (-1: a root); rest translation (N, 3), rotation (N, 4) x y z w,
    scale (N, 3); joints (J,) node index of each skin joint; inverse_bind (J, 4, 4); vertices
    (V, 3) in bind space, faces (F, 3); skin_joints (V, 4) indices into `joints`, skin_weights
    (V, 4) summing to 1 per vertex; clips by name. `source`: the file it was read from."""

    names: list[str]
    parent: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray
    joints: np.ndarray
    inverse_bind: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    skin_joints: np.ndarray
    skin_weights: np.ndarray
    clips: dict[str, Clip] = field(default_factory=dict)
    source: str = "<rig>"
    #: the joints' rotations are real (glTF exporters point each joint's +y along its bone);
    #: False for a joints file, whose joints have positions only
    oriented: bool = True

    def __post_init__(self):
        self.order = topological_order(self.parent, self.names, self.source)

    @property
    def joint_names(self) -> list[str]:
        return [self.names[j] for j in self.joints]

    def joint_index(self, name: str) -> int:
        """Index of joint `name` in `joints` (DataError naming the file and the joint)."""
        names = self.joint_names
        if name not in names:
            raise DataError(f"rig has no joint {name!r}", path=self.source, field="joints",
                            fix=f"use one of the rig's joints ({', '.join(names[:12])}"
                                f"{', ...' if len(names) > 12 else ''})")
        return names.index(name)

    def joint_parent(self) -> np.ndarray:
        """(J,) index into `joints` of each joint's nearest ancestor joint (-1: none)."""
        pos = {int(n): i for i, n in enumerate(self.joints)}
        out = np.full(len(self.joints), -1)
        for i, n in enumerate(self.joints):
            p = int(self.parent[n])
            while p >= 0 and p not in pos:
                p = int(self.parent[p])
            out[i] = pos.get(p, -1)
        return out

    def clip(self, name: str) -> Clip:
        if name not in self.clips:
            raise DataError(f"rig has no clip {name!r}", path=self.source, field="clip",
                            fix=f"use one of {sorted(self.clips)}" if self.clips
                            else "this rig has no animations: pose it at rest (clip null)")
        return self.clips[name]

    # ---- posing -----------------------------------------------------------------------------
    def local_trs(self, clip: str | None = None, time: float = 0.0):
        """(translation (N, 3), rotation (N, 4), scale (N, 3)) of every node at `time` seconds
        of `clip` (None: the rest pose). Times outside the clip hold its first or last key."""
        T, R, S = self.translation.copy(), self.rotation.copy(), self.scale.copy()
        if clip is not None:
            for ch in self.clip(clip).channels:
                value = sample_channel(ch, time)
                {"translation": T, "rotation": R, "scale": S}[ch.path][ch.node] = value
        R /= np.linalg.norm(R, axis=1, keepdims=True)
        return T, R, S

    def world_matrices(self, clip: str | None = None, time: float = 0.0) -> np.ndarray:
        """(N, 4, 4) world matrix of every node at the pose."""
        local = trs_matrices(*self.local_trs(clip, time))
        world = np.empty_like(local)
        for n in self.order:
            p = self.parent[n]
            world[n] = local[n] if p < 0 else world[p] @ local[n]
        return world

    def joint_positions(self, clip: str | None = None, time: float = 0.0) -> np.ndarray:
        """(J, 3) world position of every skin joint at the pose."""
        return self.world_matrices(clip, time)[self.joints, :3, 3]

    def bone_axes(self, clip: str | None = None, time: float = 0.0) -> np.ndarray | None:
        """(J, 3) unit +y axis of every joint at the pose (along its bone), None when the rig
        is not `oriented`."""
        if not self.oriented:
            return None
        y = self.world_matrices(clip, time)[self.joints, :3, 1]
        return y / np.maximum(np.linalg.norm(y, axis=1, keepdims=True), 1e-12)

    def skin_matrices(self, clip: str | None = None, time: float = 0.0) -> np.ndarray:
        """(J, 4, 4) T_j B_j^-1 of every joint at the pose."""
        return self.world_matrices(clip, time)[self.joints] @ self.inverse_bind

    def posed(self, clip: str | None = None, time: float = 0.0) -> np.ndarray:
        """(V, 3) vertices at the pose by linear blend skinning."""
        return skin_vertices(self.vertices, self.skin_joints, self.skin_weights,
                             self.skin_matrices(clip, time))

    def dominant_joint(self) -> np.ndarray:
        """(V,) the joint (index into `joints`) with the largest weight of each vertex."""
        return self.skin_joints[np.arange(len(self.skin_joints)), self.skin_weights.argmax(1)]


def skin_vertices(vertices: np.ndarray, skin_joints: np.ndarray, skin_weights: np.ndarray,
                  matrices: np.ndarray) -> np.ndarray:
    """Linear blend skinning: vertices (V, 3), skin_joints (V, K) int, skin_weights (V, K),
    matrices (J, 4, 4) -> (V, 3) sum_k w_k M_{j_k} [v, 1]."""
    M = np.einsum("vk,vkab->vab", skin_weights, matrices[skin_joints])  # (V, 4, 4)
    return np.einsum("vab,vb->va", M[:, :3, :3], vertices) + M[:, :3, 3]


def quat_matrices(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (N, 4) x y z w -> rotation matrices (N, 3, 3)."""
    x, y, z, w = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def trs_matrices(t: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(N, 4, 4) matrices T R S from translations (N, 3), quaternions (N, 4), scales (N, 3)."""
    M = np.zeros((len(t), 4, 4))
    M[:, :3, :3] = quat_matrices(r) * np.asarray(s, np.float64)[:, None, :]
    M[:, :3, 3] = t
    M[:, 3, 3] = 1.0
    return M


def matrix_trs(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One 4x4 affine matrix (no shear) -> translation (3,), quaternion x y z w (4,), scale (3,)."""
    m = np.asarray(m, np.float64)
    t = m[:3, 3].copy()
    s = np.linalg.norm(m[:3, :3], axis=0)
    if np.linalg.det(m[:3, :3]) < 0:
        s[0] = -s[0]
    R = m[:3, :3] / s
    w = np.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2.0
    x = np.copysign(np.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2.0, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2.0, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2.0, R[1, 0] - R[0, 1])
    q = np.array([x, y, z, w])
    return t, q / np.linalg.norm(q), s


def slerp(q0: np.ndarray, q1: np.ndarray, f: float) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (4,) by f in [0, 1] (shorter arc)."""
    d = float(q0 @ q1)
    if d < 0.0:
        q1, d = -q1, -d
    if d > 0.9995:  # nearly equal: lerp, renormalised
        q = q0 + f * (q1 - q0)
        return q / np.linalg.norm(q)
    a = np.arccos(d)
    return (np.sin((1.0 - f) * a) * q0 + np.sin(f * a) * q1) / np.sin(a)


def sample_channel(ch: Channel, time: float) -> np.ndarray:
    """The channel's value at `time` (glTF 2.0 animation sampling; times outside its keys hold
    the first or last value)."""
    t = ch.times
    if ch.interpolation == "CUBICSPLINE":
        vals = ch.values.reshape(len(t), 3, -1)  # in-tangent, value, out-tangent
        key_values = vals[:, 1]
    else:
        key_values = ch.values
    if time <= t[0] or len(t) == 1:
        return key_values[0].copy()
    if time >= t[-1]:
        return key_values[-1].copy()
    k = int(np.searchsorted(t, time, side="right")) - 1
    dt = float(t[k + 1] - t[k])
    f = (time - t[k]) / dt
    if ch.interpolation == "STEP":
        return key_values[k].copy()
    if ch.interpolation == "CUBICSPLINE":  # glTF's Hermite form, tangents scaled by dt
        p0, m0 = vals[k, 1], vals[k, 2] * dt
        p1, m1 = vals[k + 1, 1], vals[k + 1, 0] * dt
        f2, f3 = f * f, f * f * f
        v = (2 * f3 - 3 * f2 + 1) * p0 + (f3 - 2 * f2 + f) * m0 + (-2 * f3 + 3 * f2) * p1 \
            + (f3 - f2) * m1
        return v / np.linalg.norm(v) if ch.path == "rotation" else v
    if ch.path == "rotation":
        return slerp(key_values[k], key_values[k + 1], f)
    return (1.0 - f) * key_values[k] + f * key_values[k + 1]


def topological_order(parent: np.ndarray, names: list[str], source: str) -> list[int]:
    """Node indices with every parent before its children (DataError on a cycle)."""
    children: dict[int, list[int]] = {}
    for n, p in enumerate(parent):
        children.setdefault(int(p), []).append(n)
    order, stack = [], list(reversed(children.get(-1, [])))
    while stack:
        n = stack.pop()
        order.append(n)
        stack.extend(reversed(children.get(n, [])))
    if len(order) != len(parent):
        stuck = sorted(set(range(len(parent))) - set(order))
        raise DataError(f"the node hierarchy has a cycle through node {names[stuck[0]]!r}",
                        path=source, field="nodes", fix="re-export the rig from its tool")
    return order
