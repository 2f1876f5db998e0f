"""Corrective shapes: per keyframe, the skinned vertices moved onto NGC's exact posed surface.

Linear blend skinning v' = sum_j w_j M_j B_j^-1 v approximates what NGC computes exactly: the
posed shape's zero set. A few Newton steps along the posed field's gradient,
x <- x - f(x) grad f / |grad f|^2 (the gradient by finite differences: the field's relative
coordinates come from a closest-point solve, not autograd), put each skinned vertex on it. A
glTF morph target is added before skinning, so the stored offset is in bind space: with the
vertex's blended affine map x' = A v + b, the offset d solves A d = y - x'.
"""
from __future__ import annotations

import numpy as np

from .weights import INFLUENCES  # noqa: F401  (the influence count the skin is built with)


def blended(joints: np.ndarray, weights: np.ndarray, skin: np.ndarray) -> np.ndarray:
    """(V, 4, 4) per-vertex blended matrices sum_k w_k S_{j_k}; skin (J, 4, 4) = M_j B_j^-1."""
    return np.einsum("vk,vkab->vab", weights, skin[joints])


def skinned(vertices: np.ndarray, joints: np.ndarray, weights: np.ndarray,
            skin: np.ndarray) -> np.ndarray:
    """(V, 3) linear-blend-skinned vertices."""
    M = blended(joints, weights, skin)
    return np.einsum("vab,vb->va", M[:, :3, :3], vertices) + M[:, :3, 3]


def project(sdf, x: np.ndarray, steps: int, h: float, max_step: float,
            tol: float = 1e-5, regrad: int = 2) -> np.ndarray:
    """x (V, 3) moved onto sdf's zero set by up to `steps` Newton steps, each at most max_step
    long. The gradient (central differences, spacing h: six more field values a point) is
    taken afresh every `regrad` steps and kept in between (near the surface it barely turns), so
    most steps cost one field value a point. A point stops once |f| <= tol (later steps evaluate
    the rest only); a point where the field has no gradient stays."""
    x = np.array(x, dtype=np.float64)
    eye = np.eye(3) * h
    active = np.arange(len(x))
    grad = np.zeros_like(x)
    for step_i in range(int(steps)):
        if not len(active):
            break
        xa = x[active]
        if step_i % max(int(regrad), 1) == 0:
            probes = np.concatenate([xa] + [xa + s * e for e in eye for s in (1.0, -1.0)])
            v = np.asarray(sdf(probes), np.float64).reshape(7, len(xa))
            grad[active] = np.stack([(v[1 + 2 * i] - v[2 + 2 * i]) / (2.0 * h)
                                     for i in range(3)], 1)
            f = v[0]
        else:
            f = np.asarray(sdf(xa), np.float64)
        g = grad[active]
        g2 = (g * g).sum(1)
        move = (np.abs(f) > tol) & (g2 > 1e-4)
        step = -(f[move] / g2[move])[:, None] * g[move]
        length = np.linalg.norm(step, axis=1, keepdims=True)
        x[active[move]] += step * np.minimum(1.0, max_step / np.maximum(length, 1e-300))
        active = active[move]
    if len(active):  # not settled: the zero set is a jump there (a GC's boundary cuts the
        x[active] = bracket(sdf, x[active], grad[active], max_step)  # material), or it bounced
    return x


def bracket(sdf, x: np.ndarray, direction: np.ndarray, reach: float, samples: int = 11,
            iters: int = 12) -> np.ndarray:
    """x (M, 3) moved to the sign change of sdf nearest to it on the line through it along
    `direction` (within +-reach; bisection), where Newton cannot settle: at a jump of the
    field (the union's background past a GC boundary, as the extractor meshes it) or a kink
    between two GCs. A point without a sign change in reach stays."""
    d = direction / np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-300)
    s = np.linspace(-reach, reach, samples)
    v = np.asarray(sdf((x[:, None] + s[None, :, None] * d[:, None]).reshape(-1, 3)),
                   np.float64).reshape(len(x), samples)
    change = np.sign(v[:, 1:]) != np.sign(v[:, :-1])  # (M, samples - 1)
    mid = 0.5 * (s[1:] + s[:-1])
    dist = np.where(change, np.abs(mid)[None, :], np.inf)
    ok = np.isfinite(dist.min(1))
    i = dist.argmin(1)
    lo, hi = s[i], s[i + 1]
    f_lo = v[np.arange(len(x)), i]
    for _ in range(int(iters)):
        m = 0.5 * (lo + hi)
        fm = np.asarray(sdf(x + m[:, None] * d), np.float64)
        same = np.sign(fm) == np.sign(f_lo)
        lo, f_lo, hi = np.where(same, m, lo), np.where(same, fm, f_lo), np.where(same, hi, m)
    out = x.copy()
    out[ok] += (0.5 * (lo + hi))[ok, None] * d[ok]
    return out


def guide_field(shape, points: np.ndarray) -> np.ndarray:
    """The shape's field (`Shape.sdf`), and outside every GC, where that is a constant with no
    gradient, the decoder of the relatively nearest GC evaluated at the point's relative
    coordinates there: a skinned vertex that left the posed GCs is still led back to the
    surface."""
    import torch

    from ngc_gen.shape.shape import OUTSIDE

    f = shape.sdf(points).numpy().astype(np.float64)
    out = np.flatnonzero(f == OUTSIDE)  # Shape.sdf's background: in no GC
    if len(out):
        q = np.asarray(points, np.float64)[out]
        best, value = np.full(len(q), np.inf), np.zeros(len(q))
        for j, gc in enumerate(shape.gcs):  # GCs (tens), never points
            rel = np.asarray(gc.to_relative(q))
            m = gc.relative_measure(rel)
            v = shape.gc_sdf(j, torch.as_tensor(rel, dtype=torch.float32)).double().numpy()
            take = m < best
            best[take], value[take] = m[take], v[take]
        f[out] = value
    return f


def corrective_offsets(vertices: np.ndarray, joints: np.ndarray, weights: np.ndarray,
                       skin: np.ndarray, sdf, steps: int, h: float,
                       max_step: float) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (V, 3) in bind space, target (V, 3) posed positions) of one keyframe: skin
    matrices `skin` (J, 4, 4), `sdf` the posed shape's field (points (N, 3) -> (N,))."""
    M = blended(joints, weights, skin)
    x = np.einsum("vab,vb->va", M[:, :3, :3], vertices) + M[:, :3, 3]
    y = project(sdf, x, steps, h, max_step)
    d = np.linalg.solve(M[:, :3, :3], (y - x)[:, :, None])[:, :, 0]
    return d, y
