"""Corrective shapes: per keyframe, the skinned vertices moved onto NGC's exact posed surface.

Linear blend skinning v' = sum_j w_j M_j B_j^-1 v approximates what NGC computes exactly: the
posed shape's zero set. A few Newton steps along the posed field's gradient,
x <- x - f(x) grad f / |grad f|^2 (the gradient by central differences: the field's relative
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


def project(sdf, x: np.ndarray, steps: int, h: float, max_step: float) -> np.ndarray:
    """x (V, 3) moved onto sdf's zero set by `steps` Newton steps (central-difference gradient
    with spacing h; each step at most max_step long; points where the field has no gradient,
    outside every GC, stay)."""
    x = np.array(x, dtype=np.float64)
    eye = np.eye(3) * h
    for _ in range(int(steps)):
        probes = np.concatenate([x] + [x + s * e for e in eye for s in (1.0, -1.0)])
        v = np.asarray(sdf(probes), np.float64).reshape(7, len(x))
        f = v[0]
        grad = np.stack([(v[1 + 2 * i] - v[2 + 2 * i]) / (2.0 * h) for i in range(3)], 1)
        g2 = (grad * grad).sum(1)
        ok = g2 > 1e-4
        step = np.zeros_like(x)
        step[ok] = -(f[ok] / g2[ok])[:, None] * grad[ok]
        length = np.linalg.norm(step, axis=1, keepdims=True)
        step *= np.minimum(1.0, max_step / np.maximum(length, 1e-300))
        x += step
    return x


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
