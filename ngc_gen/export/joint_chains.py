"""GCs as a skeleton: a chain of joints along each GC's curve, the chains joined by a parent
tree (the template's, or one inferred from where the GCs meet).

Joint k of a GC with n joints sits at network parameter t_k = k / n of its curve (a reversed
chain, whose curve starts at the free end, at 1 - k / n) and owns the segment up to the next
one. Its world matrix is the GC's frame there: columns (binormal, tangent, normal), so the
joint's +y runs along the bone as glTF tools draw it. The same function gives the bind pose
(the GCs as meshed) and any pose (the GCs of that pose, same names): `joint_matrices`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ngc_gen.geometry import GeneralizedCylinder


class SkeletonError(ValueError):
    """A skeleton that cannot be built (no joints, unknown parent names)."""


@dataclass(frozen=True)
class Skeleton:
    """names (J,): `<gc>_<k>`; parent (J,) joint index (-1: the root); gc (J,) GC index of each
    joint; k (J,) its place in the chain; per_gc: joints per GC; reversed (G,) bool: the chain
    runs from the curve's end; gc_names (G,); gc_parent (G,) GC index (-1: root)."""

    names: list[str]
    parent: np.ndarray
    gc: np.ndarray
    k: np.ndarray
    per_gc: int
    reversed: np.ndarray
    gc_names: list[str]
    gc_parent: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def joint_t(self) -> np.ndarray:
        """(J,) network parameter t of every joint on its GC's curve."""
        t = self.k / self.per_gc
        return np.where(self.reversed[self.gc], 1.0 - t, t)

    def order(self) -> np.ndarray:
        """Joint indices with every parent before its children."""
        depth = np.zeros(self.n_joints, np.int64)
        for j in range(self.n_joints):  # joints (tens), never vertices
            p = self.parent[j]
            while p >= 0:
                depth[j] += 1
                p = self.parent[p]
        return np.argsort(depth, kind="stable")


def _curve_points(gc: GeneralizedCylinder, t: np.ndarray) -> torch.Tensor:
    s = gc.arc.s_of_t(gc.arc_of_t(torch.as_tensor(t, dtype=torch.float64)))
    return gc.curve.evaluate(s)[0]


def gc_frames(gc: GeneralizedCylinder, t: np.ndarray) -> np.ndarray:
    """(N, 4, 4) world matrices at network parameters t (N,): columns binormal, tangent, normal
    and the curve point."""
    tt = torch.as_tensor(np.asarray(t, np.float64))
    arc = gc.arc_of_t(tt)
    C, T, N, B = gc.frame(gc.arc.s_of_t(arc), tt)
    M = np.zeros((len(tt), 4, 4))
    M[:, :3, 0], M[:, :3, 1], M[:, :3, 2] = B.numpy(), T.numpy(), N.numpy()
    M[:, :3, 3], M[:, 3, 3] = C.numpy(), 1.0
    return M


def infer_parents(gcs: list[GeneralizedCylinder], samples: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """(parent (G,) GC index, -1 for the root; reversed (G,) bool) for GCs without a template:
    the root is the GC of the largest volume; the others join the tree one at a time by the
    shortest gap from one of their ends to a curve already in the tree (Prim's tree), the end
    nearer it becoming the chain's start."""
    G = len(gcs)
    t = np.linspace(0.0, 1.0, samples)
    pts = np.stack([_curve_points(g, t).numpy() for g in gcs])  # (G, S, 3)
    vol = [g.length * float(g.radii_at(torch.tensor([0.5], dtype=torch.float64)).prod())
           for g in gcs]
    ends = pts[:, [0, -1]]  # (G, 2, 3)
    # gap[c, e, p]: end e of GC c to the curve of GC p
    gap = np.linalg.norm(ends[:, :, None, None] - pts[None, None], axis=-1).min(-1)
    parent, rev = np.full(G, -1), np.zeros(G, bool)
    tree = [int(np.argmax(vol))]
    while len(tree) < G:
        out = [c for c in range(G) if c not in tree]
        sub = gap[out][:, :, tree]  # (O, 2, T)
        c, e, p = np.unravel_index(np.argmin(sub), sub.shape)
        parent[out[c]], rev[out[c]] = tree[p], bool(e == 1)
        tree.append(out[c])
    return parent, rev


def build_skeleton(gcs: list[GeneralizedCylinder], per_gc: int,
                   parents: dict[str, str | None] | None = None) -> Skeleton:
    """The skeleton of GCs: `per_gc` joints each, chains joined by `parents` (GC name -> its
    parent's name or None; the template's tree) or, when None or not naming every GC, by
    `infer_parents`. A chain's first joint hangs from the parent's joint whose segment holds
    the point of the parent curve nearest to the chain's start."""
    if int(per_gc) < 1:
        raise SkeletonError(f"joints per GC must be >= 1, got {per_gc}")
    names = [g.name for g in gcs]
    if parents is not None and all(n in parents for n in names):
        unknown = sorted({p for p in parents.values() if p is not None} - set(names))
        if unknown:
            raise SkeletonError(f"the parent tree names GCs {unknown} the shape does not have")
        gp = np.array([-1 if parents[n] is None else names.index(parents[n]) for n in names])
        rev = np.zeros(len(gcs), bool)
        if (gp < 0).sum() != 1:
            gp, rev = infer_parents(gcs)
    else:
        gp, rev = infer_parents(gcs)
    n = int(per_gc)
    G = len(gcs)
    gc_idx, k = np.repeat(np.arange(G), n), np.tile(np.arange(n), G)
    parent = np.where(k > 0, np.arange(G * n) - 1, -1)
    dense = np.linspace(0.0, 1.0, 257)
    for g in range(G):
        p = gp[g]
        if p < 0:
            continue
        start = _curve_points(gcs[g], np.array([1.0 if rev[g] else 0.0])).numpy()[0]
        curve = _curve_points(gcs[p], dense).numpy()
        tp = dense[np.argmin(np.linalg.norm(curve - start, axis=1))]
        tp = 1.0 - tp if rev[p] else tp
        parent[g * n] = p * n + min(int(tp * n), n - 1)
    skel_names = [f"{names[g]}_{kk}" for g, kk in zip(gc_idx, k)]
    return Skeleton(skel_names, parent, gc_idx, k, n, rev, names, gp)


def joint_matrices(skeleton: Skeleton, gcs: list[GeneralizedCylinder]) -> np.ndarray:
    """(J, 4, 4) world matrix of every joint for GCs `gcs` (the skeleton's GCs, this pose)."""
    if [g.name for g in gcs] != skeleton.gc_names:
        raise SkeletonError(f"a pose must have the skeleton's GCs {skeleton.gc_names}, got "
                            f"{[g.name for g in gcs]}")
    t = skeleton.joint_t()
    out = np.empty((skeleton.n_joints, 4, 4))
    for g, gc in enumerate(gcs):  # GCs (tens), never vertices
        m = skeleton.gc == g
        M = gc_frames(gc, t[m])
        if skeleton.reversed[g]:  # the bone runs toward the curve's start
            M[:, :3, :2] = -M[:, :3, :2]
        out[m] = M
    return out


def local_matrices(skeleton: Skeleton, world: np.ndarray) -> np.ndarray:
    """(..., J, 4, 4) world matrices -> each joint's matrix relative to its parent."""
    par = skeleton.parent
    inv = np.linalg.inv(world[..., np.maximum(par, 0), :, :])
    local = inv @ world
    root = par < 0
    local[..., root, :, :] = world[..., root, :, :]
    return local
