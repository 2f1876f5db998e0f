"""0 A.D. files as a `Rig`: a PMD's skin and bind pose, its standard skeleton's bone tree and
PSA clips.

PMD and PSA store every bone's transform in model space; a `Rig` stores each node's transform
relative to its parent, so both are made local with the skeleton's parents (vectorised over
bones and frames): q_local = conj(q_parent) q, t_local = R(q_parent)^T (t - t_parent).
Which standard skeleton a PMD uses is not written in it: the skeleton with its bone count whose
tree joins the PMD's rest bone positions by the shortest bones is taken (a wrong tree of the
same size joins distant bones).
"""
from __future__ import annotations

import numpy as np

from ngc_gen.data.errors import DataError

from .rig import Channel, Clip, Rig, quat_matrices
from .zeroad_formats import PMD, PSA, Skeleton


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (..., 4) x y z w."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], -1)


def local_transforms(t: np.ndarray, q: np.ndarray, parent: np.ndarray):
    """Model-space bone transforms t (..., B, 3), q (..., B, 4) -> local to each bone's parent
    (the root's stay as they are)."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    has = parent >= 0
    p = np.where(has, parent, 0)
    qp, tp = q[..., p, :], t[..., p, :]
    conj = qp * np.array([-1.0, -1.0, -1.0, 1.0])
    ql = np.where(has[:, None], quat_mul(conj, q), q)
    R = quat_matrices(qp)  # (..., B, 3, 3)
    tl = np.where(has[:, None], np.einsum("...ji,...j->...i", R, t - tp), t)
    return tl, ql


def tree_length(skeleton: Skeleton, positions: np.ndarray) -> float:
    """Total length of the skeleton's bones (child - parent) over bone positions (B, 3)."""
    has = skeleton.parent >= 0
    return float(np.linalg.norm(positions[has] - positions[skeleton.parent[has]], axis=1).sum())


def choose_skeleton(pmd: PMD, skeletons: list[Skeleton]) -> Skeleton:
    """The skeleton of `pmd`: of those with its bone count, the one whose tree is shortest over
    the PMD's rest bone positions. DataError when none has its bone count."""
    n = len(pmd.bone_translation)
    fits = [s for s in skeletons if len(s.names) == n]
    if not fits:
        raise DataError(f"no standard skeleton has its {n} bones", path=pmd.source,
                        fix="add the skeleton XML it was exported with")
    return min(fits, key=lambda s: tree_length(s, pmd.bone_translation))


def psa_clip(psa: PSA, parent: np.ndarray, name: str | None = None) -> Clip:
    """A PSA as a clip of every bone's local translation and rotation, one key per frame."""
    if psa.translation.shape[1] != len(parent):
        raise DataError(f"it animates {psa.translation.shape[1]} bones, the skeleton has "
                        f"{len(parent)}", path=psa.source, fix="pair it with its own skeleton")
    tl, ql = local_transforms(psa.translation, psa.rotation, parent)
    times = np.arange(len(tl), dtype=np.float64) * psa.frame_length
    channels = []
    for b in range(len(parent)):
        channels.append(Channel(b, "translation", times, tl[:, b]))
        channels.append(Channel(b, "rotation", times, ql[:, b]))
    return Clip(name or psa.name, tuple(channels))


def pmd_rig(pmd: PMD, skeleton: Skeleton, clips: dict[str, PSA] | None = None) -> Rig:
    """The rig of a PMD posed by `skeleton`'s tree, with `clips` (name -> PSA) of the same
    bones. Vertices without skin weight are bound to bone 0 (the root)."""
    B = len(pmd.bone_translation)
    if len(skeleton.names) != B:
        raise DataError(f"the skeleton {skeleton.id!r} has {len(skeleton.names)} bones, the "
                        f"PMD {B}", path=pmd.source, fix="pair it with its own skeleton")
    tl, ql = local_transforms(pmd.bone_translation, pmd.bone_rotation, skeleton.parent)
    world = np.zeros((B, 4, 4))
    qn = pmd.bone_rotation / np.linalg.norm(pmd.bone_rotation, axis=1, keepdims=True)
    world[:, :3, :3] = quat_matrices(qn)
    world[:, :3, 3] = pmd.bone_translation
    world[:, 3, 3] = 1.0
    weights = pmd.weights.copy()
    total = weights.sum(1)
    weights = np.where(total[:, None] > 1e-9, weights / np.maximum(total, 1e-9)[:, None],
                       np.array([1.0, 0.0, 0.0, 0.0]))
    joints = np.where(pmd.bones >= 0, pmd.bones, 0)
    rig = Rig(names=list(skeleton.names), parent=skeleton.parent.copy(), translation=tl,
              rotation=ql, scale=np.ones((B, 3)), joints=np.arange(B),
              inverse_bind=np.linalg.inv(world), vertices=pmd.positions.copy(),
              faces=pmd.faces.copy(), skin_joints=joints, skin_weights=weights,
              source=pmd.source, oriented=False)
    for name, psa in (clips or {}).items():
        rig.clips[name] = psa_clip(psa, skeleton.parent, name)
    return rig
