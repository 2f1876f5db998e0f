"""Skin weights from the NGC field: which GC holds a vertex, and where along its curve.

Per GC g, a vertex's share is exp(-(f_g - f_min) / blend) x s(rho_g): f_g the GC's own SDF at
the vertex (the union takes the smallest, so the GC whose surface the vertex is on wins), blend
a width in world units (shares cross smoothly where two GCs' surfaces meet), and s a smoothstep
of the relative radius rho_g that is 1 inside rho <= 1 - falloff and 0 at the GC's boundary (a
share never jumps when a vertex leaves a GC). Along the curve the share goes to the chain's two
joints around the vertex's t (tents centred on the joints' segments), so a bend blends the two
bones. The largest 4 of all those are kept and normalised (glTF's JOINTS_0 / WEIGHTS_0).
"""
from __future__ import annotations

import numpy as np
import torch

from .joint_chains import Skeleton

INFLUENCES = 4


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def chain_tents(t: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Network parameters t (V,) on a chain of n joints -> (k (V, 2) joint places, w (V, 2))
    tents centred on the segments' middles (k + 0.5) / n, clamped at the chain's ends."""
    x = np.clip(t, 0.0, 1.0) * n - 0.5
    k0 = np.floor(x)
    f = x - k0
    k = np.stack([k0, k0 + 1], 1)
    w = np.stack([1.0 - f, f], 1)
    return np.clip(k, 0, n - 1).astype(np.int64), w


def skin_weights(shape, skeleton: Skeleton, vertices: np.ndarray, blend: float,
                 falloff: float) -> tuple[np.ndarray, np.ndarray]:
    """(joints (V, 4) int, weights (V, 4) float summing to 1) of `vertices` (V, 3) on `shape`
    (a `ngc_gen.shape.Shape` whose GCs the skeleton was built on)."""
    V = np.asarray(vertices, np.float64)
    G, n = len(shape.gcs), skeleton.per_gc
    sdf = np.full((len(V), G), np.inf)
    rho = np.full((len(V), G), np.inf)
    tpar = np.zeros((len(V), G))
    for g, gc in enumerate(shape.gcs):  # GCs (tens), never vertices
        rel, measure = gc.relative_inside(V)
        inside = np.flatnonzero(measure <= 1.0)
        rho[:, g] = np.sqrt(measure)
        tpar[:, g] = (np.nan_to_num(np.asarray(rel)[:, 0]) + 1.0) * 0.5
        if len(inside):
            r = torch.as_tensor(np.asarray(rel)[inside], dtype=torch.float32)
            sdf[inside, g] = shape.gc_sdf(g, r).double().numpy()
    none = ~np.isfinite(sdf).any(1)
    if none.any():  # on no GC (a vertex past every boundary by rounding): the nearest one
        near = np.argmin(rho[none], 1)
        sdf[np.flatnonzero(none), near] = 0.0
    share = np.exp(-(sdf - sdf.min(1, keepdims=True)) / max(blend, 1e-12))
    share *= np.where(np.isfinite(sdf), _smoothstep((1.0 - rho) / max(falloff, 1e-12)), 0.0)
    share[none] = np.where(np.isfinite(sdf[none]), 1.0, 0.0)
    t = np.where(skeleton.reversed[None, :], 1.0 - tpar, tpar)
    k, w = chain_tents(t.ravel(), n)  # (V * G, 2)
    joints = (np.arange(G)[None, :, None] * n + k.reshape(len(V), G, 2)).reshape(len(V), -1)
    weights = (share[:, :, None] * w.reshape(len(V), G, 2)).reshape(len(V), -1)
    # a joint met twice (both tents clamped at a chain's end) keeps the sum
    order = np.argsort(joints, 1)
    joints, weights = np.take_along_axis(joints, order, 1), np.take_along_axis(weights, order, 1)
    dup = np.zeros_like(joints, bool)
    dup[:, 1:] = joints[:, 1:] == joints[:, :-1]
    for c in range(joints.shape[1] - 1, 0, -1):  # columns (2G), never vertices
        m = dup[:, c]
        weights[m, c - 1] += weights[m, c]
    weights[dup] = 0.0
    top = np.argsort(-weights, 1)[:, :INFLUENCES]
    J, W = np.take_along_axis(joints, top, 1), np.take_along_axis(weights, top, 1)
    total = W.sum(1, keepdims=True)
    if (total <= 0).any():  # every share vanished: the GC holding most of it, its first joint
        bad = total[:, 0] <= 0
        J[bad, 0], W[bad] = np.argmin(rho[bad], 1) * n, np.eye(INFLUENCES)[0]
        total = W.sum(1, keepdims=True)
    W = W / total
    J[W == 0] = 0
    return J.astype(np.int64), W
