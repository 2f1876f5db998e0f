"""One generalized cylinder per skeleton branch (docs/autogc.md).

Curve: a least-squares cubic Bezier through the branch polyline, parameterised by normalised arc
length, ends interpolated (the basis is ``geometry.curves.BezierCurve``'s: a curve is linear in
its control points). A branch too curved for one cubic (a torus' loop) is split in two at half
its length until the cubic stays within a fraction of the local thickness.
Frame: ``up`` turned about the start tangent so the branch's cross-sections spread most along
the frame's y (r_y >= r_z). Radii per key: the smallest ellipse holding the branch's own surface
points near that key; caps: the extent of those points past the ends. Coverage of the whole
surface is repaired afterwards (``coverage.grow_to_cover``).
"""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.geometry import BezierCurve, GeneralizedCylinder

from ngc_gen.data.autogc.radii import ellipse_radii
from ngc_gen.data.autogc.branches import Branch

OUTLIER = 1.6  # a point farther out than this x the median of its key window is not held


def bezier_basis(degree: int, s: np.ndarray) -> np.ndarray:
    """(N, degree+1) Bernstein basis at s (N,), from the one Bezier implementation: each column
    is a curve whose control points are one-hot (x picks column j, y and z are unused)."""
    eye = np.eye(degree + 1)
    st = torch.as_tensor(np.asarray(s, dtype=np.float64))
    cols = [BezierCurve(np.stack([eye[j], np.zeros(degree + 1), np.zeros(degree + 1)], 1))
            .evaluate(st)[0][:, 0].numpy() for j in range(degree + 1)]
    return np.stack(cols, axis=1)


def resample(points: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A polyline (P, 3) resampled at n points evenly spaced in arc length, and those arc
    lengths normalised to [0, 1] at the input points (P,)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    s = arc / arc[-1] if arc[-1] > 0 else np.linspace(0.0, 1.0, len(points))
    u = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(u, s, points[:, k]) for k in range(3)], axis=1), s


def fit_cubic(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Control points (4, 3) of the least-squares cubic through a polyline (ends interpolated,
    parameters by arc length) and the largest distance of the resampled polyline from it."""
    P, _ = resample(points, 64)
    s = np.linspace(0.0, 1.0, len(P))
    B = bezier_basis(3, s)
    ctrl = np.empty((4, 3))
    ctrl[0], ctrl[3] = P[0], P[-1]
    rhs = P - B[:, :1] * ctrl[0] - B[:, 3:] * ctrl[3]
    ctrl[1:3] = np.linalg.lstsq(B[:, 1:3], rhs, rcond=None)[0]
    dense = bezier_basis(3, np.linspace(0.0, 1.0, 256)) @ ctrl
    dev = np.sqrt(((P[:, None] - dense[None]) ** 2).sum(-1).min(1)).max()
    return ctrl, float(dev)


def split_curved(branch: Branch, tolerance: float, max_depth: int = 3) -> list[Branch]:
    """The branch, or its halves (recursively), so each is fitted by one cubic within
    ``tolerance`` x its length (or its mean local thickness, if larger) and turns by at most
    about a half circle (chord >= 0.6 x length)."""
    _, dev = fit_cubic(branch.points) if len(branch.points) > 1 else (None, 0.0)
    allowed = max(tolerance * branch.length, float(branch.radius.mean()))
    chord = float(np.linalg.norm(branch.points[-1] - branch.points[0]))
    curled = chord < 0.6 * branch.length  # turns by more than a half circle (a loop cut open)
    if (dev <= allowed and not curled) or max_depth == 0 or len(branch.points) < 5:
        return [branch]
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(branch.points, axis=0), axis=1))]
    m = int(np.clip(np.searchsorted(arc, arc[-1] / 2), 2, len(arc) - 3))
    a = Branch(branch.points[: m + 1], branch.radius[: m + 1], (branch.junction[0], False), branch.component)
    b = Branch(branch.points[m:], branch.radius[m:], (False, branch.junction[1]), branch.component)
    return split_curved(a, tolerance, max_depth - 1) + split_curved(b, tolerance, max_depth - 1)


def split_bulb(branch: Branch, ratio: float, min_length: float,
               section: np.ndarray | None = None) -> list[Branch]:
    """An end branch that ends in a part thicker than what joins it to the body (a head on its
    neck), as two branches split where that part starts; otherwise [branch].

    Oriented junction -> free end, for each node k: r_d the median cross-section radius from k
    to the free end, r_p the median over as much arc just before k. A split needs r_d / r_p >=
    ``ratio`` at some k whose end part is at least ``min_length`` x r_d long and whose rest
    ``min_length`` x r_p (a foot or a rounded tip is too short to count; a branch widening
    toward its free end by more than ``ratio`` counts, a tail thinning toward it never does).
    The cut is where, coming from the free end, the radius first falls below sqrt(r_d r_p) of
    the k with the largest ratio (the medians alone would place it anywhere along the neck).
    ``section`` (P,): the radius per node (NaN: unknown), e.g. the mean distance of the surface
    samples nearest to the node, which an off-centre skeleton does not shrink as it does
    branch.radius (the distance to the nearest surface); default branch.radius."""
    if ratio <= 0 or branch.junction[0] == branch.junction[1] or len(branch.points) < 6:
        return [branch]
    flip = branch.junction[1]  # make node 0 the junction end
    S = branch.radius if section is None else np.asarray(section, dtype=np.float64)
    P, R = (branch.points[::-1], S[::-1]) if flip else (branch.points, S)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    n = len(P)
    k = np.arange(n)[:, None]
    j = np.arange(n)[None, :]
    distal = np.where(j >= k, R[None, :], np.nan)
    before = (arc[None, :] < arc[:, None]) & (arc[None, :] >= 2 * arc[:, None] - arc[-1])
    finite = np.isfinite(R)[None, :]
    ok = (before & finite).any(1) & (np.isfinite(distal).any(1))
    r_d = np.zeros(n)
    r_p = np.full(n, np.inf)
    r_d[ok] = np.nanmedian(distal[ok], axis=1)
    r_p[ok] = np.nanmedian(np.where(before, R[None, :], np.nan)[ok], axis=1)
    long_enough = ((arc[-1] - arc) >= min_length * r_d) & (arc >= min_length * r_p)
    score = np.where(long_enough & ok, r_d / r_p, 0.0)
    best = int(np.argmax(score))
    if score[best] < ratio:
        return [branch]
    thin = np.flatnonzero(R < np.sqrt(r_d[best] * r_p[best]))  # NaN: not thin
    m = int(thin.max()) + 1 if len(thin) else best
    if m < 2 or m > n - 3 or arc[-1] - arc[m] < min_length * r_d[best]:
        return [branch]  # (the thick end part past the last thin node is too short)
    T = branch.radius[::-1] if flip else branch.radius
    a = Branch(P[: m + 1], T[: m + 1], (True, False), branch.component)
    b = Branch(P[m:], T[m:], (False, False), branch.component)
    if flip:
        a = Branch(a.points[::-1], a.radius[::-1], (False, True), a.component)
        b = Branch(b.points[::-1], b.radius[::-1], (False, False), b.component)
        return [b, a]
    return [a, b]


def _start_up(tangent: np.ndarray) -> np.ndarray:
    """A unit vector normal to the tangent: the world axis least aligned with it, made normal."""
    axis = np.eye(3)[int(np.argmin(np.abs(tangent)))]
    up = axis - (axis @ tangent) * tangent
    return up / np.linalg.norm(up)


def _gc(name, ctrl, up, keys, caps) -> GeneralizedCylinder:
    return GeneralizedCylinder.from_dict({"name": name, "curve": {"type": "bezier", "points": ctrl.tolist()},
                                          "up": [float(x) for x in up], "keys": keys,
                                          "caps": [float(c) for c in caps]})


def branch_gc(branch: Branch, points: np.ndarray, name: str, n_keys: int = 5,
              margin: float = 0.05) -> GeneralizedCylinder:
    """The GC of one branch holding its own surface points (P, 3) (radii and caps grown by
    ``margin``), except points farther out than ``OUTLIER`` x the median of their key window
    (where a limb meets its parent, the parent's surface: the parent's GC grows to hold them);
    where a key has no points it takes the nearest key's radii."""
    floor = max(float(branch.radius.max()) * 0.05, 1e-3)
    if len(branch.points) < 2 or branch.length < 1e-6:  # a lone node: a short straight piece
        c = branch.points.mean(axis=0)
        r = max(float(branch.radius.max()), floor)
        d = np.array([1.0, 0.0, 0.0]) * r / 2
        ctrl = np.stack([c - d, c - d / 3, c + d / 3, c + d])
    else:
        ctrl, _ = fit_cubic(branch.points)
    tangent = ctrl[1] - ctrl[0] if np.linalg.norm(ctrl[1] - ctrl[0]) > 1e-9 else ctrl[3] - ctrl[0]
    T0 = tangent / np.linalg.norm(tangent)
    up = _start_up(T0)
    unit = _gc(name, ctrl, up, [{"t": 0.0, "radii": [1.0, 1.0]}], (1.0, 1.0))
    rel = np.asarray(unit.to_relative(points)) if len(points) else np.zeros((0, 3))
    tube = np.abs(rel[:, 0]) <= 1.0
    if tube.sum() >= 3:  # turn the frame so the cross-sections spread most along y
        _, vec = np.linalg.eigh(np.cov(rel[tube, 1:].T))
        c, s = vec[:, 1] * (1.0 if vec[np.argmax(np.abs(vec[:, 1])), 1] > 0 else -1.0)
        up = c * up + s * np.cross(T0, up)  # the RMF is turned by the same angle everywhere
        rel[:, 1:] = rel[:, 1:] @ np.array([[c, -s], [s, c]])
    t = (np.clip(rel[:, 0], -1.0, 1.0) + 1.0) / 2.0
    key_t = np.linspace(0.0, 1.0, n_keys)
    if len(branch.points) > 1:
        thick = np.interp(key_t, resample(branch.points, 2)[1], branch.radius)
    else:
        thick = np.full(n_keys, float(branch.radius.max()))
    radii = np.full((n_keys, 2), np.nan)
    width = 1.0 / (n_keys - 1)
    for k, tk in enumerate(key_t):  # radii lerp between keys: hold both adjacent intervals
        sel = tube & (np.abs(t - tk) <= width * 1.0001)
        if sel.sum() >= 10:  # leave far outliers (another part's surface at a joint) to others
            r = np.hypot(rel[:, 1], rel[:, 2])
            sel &= r <= OUTLIER * np.median(r[sel])
        if sel.sum() >= 3:
            radii[k] = ellipse_radii(rel[sel, 1], rel[sel, 2], floor)
    have = np.flatnonzero(~np.isnan(radii[:, 0]))
    for k in np.flatnonzero(np.isnan(radii[:, 0])):  # no points there: the nearest key's radii
        radii[k] = radii[have[np.argmin(np.abs(have - k))]] if len(have) else max(float(thick[k]), floor)
    radii *= 1.0 + margin
    # (a, b) with these radii: unit-radius offsets over the radii lerped at each point's t
    r_at = np.stack([np.interp(t, key_t, radii[:, j]) for j in range(2)], axis=1)
    ab2 = ((rel[:, 1:] / r_at) ** 2).sum(axis=1)
    caps = []
    for end, past, along in ((0, rel[:, 0] < -1.0, -1.0 - rel[:, 0]), (-1, rel[:, 0] > 1.0, rel[:, 0] - 1.0)):
        end_r = float(np.sqrt(np.prod(radii[end])))
        if past.any():
            slack = np.sqrt(np.clip(1.0 - ab2[past], 0.3, None))
            caps.append(max(float((along[past] / slack).max()) * (1.0 + margin), 0.25 * end_r))
        else:
            caps.append(0.5 * end_r)
    keys = [{"t": float(tk), "radii": [float(r) for r in rr]} for tk, rr in zip(key_t, radii)]
    return _gc(name, ctrl, up, keys, caps)
