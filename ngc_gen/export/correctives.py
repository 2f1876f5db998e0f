"""Corrective shapes: per keyframe, the skinned vertices moved onto NGC's exact posed surface.

Linear blend skinning v' = sum_j w_j M_j B_j^-1 v approximates what NGC computes exactly: the
posed shape's zero set. Each skinned vertex is moved onto it along its skinned normal (the
rest normal through the vertex's blended map, A^-T n): secant steps on f(x + s n), kept in a
bracket once the sign changes (regula falsi), one field value a step, stopping at |f| <= tol.
A vertex already within tol costs one field value; one that does not settle (no root near
it along its normal) takes Newton steps along the field's gradient (`project`; the gradient
by finite differences: the field's relative coordinates come from a closest-point solve, not
autograd). Where skinning folds a joint's inside into its neighbour, adjacent vertices' rays
reach different sheets of the posed surface and the faces between them span the crease off it
(`unfold` smooths those fins away). A glTF morph target is added before skinning, so the stored
offset is in bind space: with the vertex's blended affine map x' = A v + b, the offset d solves
A d = y - x'.
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


def along_line(sdf, x: np.ndarray, d: np.ndarray, f0: np.ndarray, steps: int,
               max_step: float, tol: float, outside: float) -> tuple[np.ndarray, np.ndarray]:
    """x (M, 3) moved to a zero of sdf on the line x + s d (d (M, 3) unit, f0 = sdf(x)):
    secant steps (the first with slope 1, as a distance field has along its normal), each at
    most max_step, until the sign changes; then inside that bracket regula falsi (Illinois),
    or bisection where an end is outside every GC (f == outside, the field's background: it
    jumps there, where a GC's boundary cuts the material, and the mesher's surface is the
    jump: there the point ends mid-bracket). Only unsettled points are evaluated.
    -> (points (M, 3), settled (M,) bool: |f| <= tol or bracketed)."""
    n = len(x)
    sa, fa = np.zeros(n), np.asarray(f0, np.float64).copy()
    sb = np.clip(-fa, -max_step, max_step)
    lo, hi, flo, fhi = (np.full(n, np.nan) for _ in range(4))  # the bracket, once seen
    jump = np.zeros(n, bool)  # the bracket has an end outside every GC: bisect
    best, fbest = np.zeros(n), np.abs(fa)
    active = np.flatnonzero(np.abs(fa) > tol)
    for _ in range(int(steps)):
        if not len(active):
            break
        a = active
        fb = np.asarray(sdf(x[a] + sb[a, None] * d[a]), np.float64)
        better = np.abs(fb) < fbest[a]
        best[a[better]], fbest[a[better]] = sb[a[better]], np.abs(fb[better])
        new = np.isnan(lo[a]) & (np.sign(fb) != np.sign(fa[a]))
        i = a[new]
        lo[i], flo[i], hi[i], fhi[i] = sa[i], fa[i], sb[i], fb[new]
        jump[a] |= ~np.isnan(lo[a]) & ((fb == outside) | (fa[a] == outside))
        old = ~np.isnan(lo[a]) & ~new
        keep_hi = old & (np.sign(fb) == np.sign(flo[a]))  # the new point replaces lo
        keep_lo = old & ~keep_hi
        i, j = a[keep_hi], a[keep_lo]
        lo[i], flo[i], fhi[i] = sb[i], fb[keep_hi], 0.5 * fhi[i]
        hi[j], fhi[j], flo[j] = sb[j], fb[keep_lo], 0.5 * flo[j]
        slope = (fb - fa[a]) / np.where(sb[a] == sa[a], 1.0, sb[a] - sa[a])
        slope = np.where(np.abs(slope) > 1e-3, slope, 1.0)
        sa[a], fa[a] = sb[a], fb
        sb[a] -= np.clip(fb / slope, -max_step, max_step)
        k = a[~np.isnan(lo[a])]
        falsi = lo[k] - flo[k] * (hi[k] - lo[k]) / np.where(fhi[k] == flo[k], 1.0,
                                                             fhi[k] - flo[k])
        sb[k] = np.where(jump[k], 0.5 * (lo[k] + hi[k]), falsi)
        active = a[(np.abs(fb) > tol) & (np.isnan(lo[a]) | (np.abs(hi[a] - lo[a]) > tol))]
    bracketed = ~np.isnan(lo) & (fbest > tol)
    best[bracketed & jump] = 0.5 * (lo + hi)[bracketed & jump]
    return x + best[:, None] * d, (fbest <= tol) | bracketed


def _longest_edge(p: np.ndarray, faces: np.ndarray) -> np.ndarray:
    return np.linalg.norm(p[faces[:, [1, 2, 0]]] - p[faces], axis=2).max(1)


def unfold(sdf, x: np.ndarray, y: np.ndarray, faces: np.ndarray, rest_edge: np.ndarray,
           fold: dict, steps: int, h: float, max_step: float, tol: float) -> np.ndarray:
    """y (V, 3), skinned vertices x moved onto the zero set, with the fins of folds smoothed
    away. Where skinning folds a joint's inside into its neighbour (a hind leg swung back into
    the torso), adjacent vertices' normal rays reach different sheets of the posed surface (the
    leg's, the torso's) and the faces between them span the crease, off the surface: a few
    dozen such faces held most of a walk frame's Chamfer. A face is a fin when its longest edge
    grew more than fold["stretch"] x over skinning's and its centroid is off the zero set by
    more than fold["off"] x its mean rest edge `rest_edge` (F,) (only stretched faces are
    evaluated); its vertices take their edge neighbours' mean offset y - x (the offset field
    smoothed, not the positions: thin parts do not shrink) and are projected onto the zero set
    again (`project`), fold["rounds"] times."""
    import trimesh
    from trimesh.smoothing import laplacian_calculation

    y = np.array(y, dtype=np.float64)
    mean = laplacian_calculation(trimesh.Trimesh(x, faces, process=False)).tocsr()
    skin_edge = _longest_edge(x, faces)
    for _ in range(int(fold["rounds"])):
        cand = np.flatnonzero(_longest_edge(y, faces) > fold["stretch"] * skin_edge)
        if not len(cand):
            break
        off = np.abs(np.asarray(sdf(y[faces[cand]].mean(1)), np.float64))
        fins = cand[off > fold["off"] * rest_edge[cand]]
        if not len(fins):
            break
        v = np.unique(faces[fins])
        y[v] = project(sdf, x[v] + mean[v] @ (y - x), steps, h, max_step, tol)
    return y


def skinned_normals(normals: np.ndarray, M: np.ndarray) -> np.ndarray:
    """(V, 3) rest normals through the blended maps M (V, 4, 4): A^-T n, unit."""
    n = np.linalg.solve(np.swapaxes(M[:, :3, :3], 1, 2), normals[:, :, None])[:, :, 0]
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def corrective_offsets(vertices: np.ndarray, normals: np.ndarray, faces: np.ndarray,
                       joints: np.ndarray, weights: np.ndarray, skin: np.ndarray, sdf,
                       steps: int, h: float, max_step: float, tol: float,
                       fold: dict) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (V, 3) in bind space, target (V, 3) posed positions) of one keyframe: rest
    vertices and normals (V, 3), faces (F, 3), skin matrices `skin` (J, 4, 4), `sdf` the posed
    shape's field (points (N, 3) -> (N,)), `fold` `unfold`'s settings (rounds 0: off)."""
    from ngc_gen.shape.shape import OUTSIDE

    M = blended(joints, weights, skin)
    x = np.einsum("vab,vb->va", M[:, :3, :3], vertices) + M[:, :3, 3]
    f0 = np.asarray(sdf(x), np.float64)
    y, ok = along_line(sdf, x, skinned_normals(normals, M), f0, steps, max_step, tol, OUTSIDE)
    if not ok.all():  # no sign change along the normal within reach: the field's gradient
        bad = np.flatnonzero(~ok)
        z = project(sdf, x[bad], steps, h, max_step, tol)
        gain = np.abs(np.asarray(sdf(z), np.float64)) < np.abs(f0[bad])
        y[bad[gain]] = z[gain]  # a point it cannot bring nearer the surface keeps skinning's
    rest_edge = np.linalg.norm(vertices[faces[:, [1, 2, 0]]] - vertices[faces], axis=2).mean(1)
    y = unfold(sdf, x, y, faces, rest_edge, fold, steps, h, max_step, tol)
    d = np.linalg.solve(M[:, :3, :3], (y - x)[:, :, None])[:, :, 0]
    return d, y
