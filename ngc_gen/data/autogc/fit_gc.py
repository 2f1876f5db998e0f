"""Fit a curved GC to a point set (one part of a mesh): the tool behind the shipped multi-GC
annotations, and usable for any mesh whose parts are separate pieces.

Axis: centroids of slices along the points' principal axis, fitted by a least-squares Bezier;
keys: per-t elliptic radii that hold every point of their neighbourhood; caps: the shortest
half-ellipsoids that hold the points past the ends. Verified with `contains` and grown if needed.
"""
from __future__ import annotations

import numpy as np

from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis

from ngc_gen.data.autogc.radii import ellipse_radii, principal_axes
from ngc_gen.data.errors import DataError


def _bezier_lsq(points: np.ndarray, degree: int) -> np.ndarray:
    """Control points (degree+1, 3) of the Bezier through ordered points (chord-length
    parameters), ends interpolated, interior least squares."""
    chord = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    s = chord / chord[-1]
    B = bernstein_basis(degree, s)
    ctrl = np.empty((degree + 1, 3))
    ctrl[0], ctrl[-1] = points[0], points[-1]
    if degree > 1:
        rhs = points - B[:, :1] * ctrl[0] - B[:, -1:] * ctrl[-1]
        ctrl[1:-1] = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)[0]
    return ctrl


def fit_gc(points: np.ndarray, name: str, degree: int = 3, n_keys: int = 5, margin: float = 0.08,
           min_radius: float = 5e-3, end_fraction: float = 0.08) -> GeneralizedCylinder:
    """A GC of a Bezier curve of `degree` with `n_keys` keys enclosing every point (N, 3)."""
    P = np.asarray(points, dtype=np.float64)
    center, axes = principal_axes(P)
    s = (P - center) @ axes[0]
    lo, hi = s.min(), s.max()
    if not hi - lo > 1e-6:
        raise DataError("points have no extent", gc=name)
    # slice centroids between the ends, pulled in by end_fraction so caps cover the tips
    n_slices = max(degree + 1, 8)
    edges = np.linspace(lo, hi, n_slices + 1)
    idx = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_slices - 1)
    counts = np.bincount(idx, minlength=n_slices)
    sums = np.stack([np.bincount(idx, P[:, k], minlength=n_slices) for k in range(3)], 1)
    cents = sums[counts > 0] / counts[counts > 0, None]
    if len(cents) < degree + 1:
        degree = max(1, len(cents) - 1)
    a, b = lo + end_fraction * (hi - lo), hi - end_fraction * (hi - lo)
    cents[0] += (a - (cents[0] - center) @ axes[0]) * axes[0]
    cents[-1] += (b - (cents[-1] - center) @ axes[0]) * axes[0]
    ctrl = _bezier_lsq(cents, degree) if len(cents) > 1 else np.stack([cents[0] + a * axes[0],
                                                                       cents[0] + b * axes[0]])
    base = {"name": name, "curve": {"type": "bezier", "points": ctrl.tolist()},
            "up": axes[1].tolist(), "keys": [{"t": 0.0, "radii": [1.0, 1.0]}], "caps": [1.0, 1.0]}
    unit = GeneralizedCylinder.from_dict(base)
    rel = np.asarray(unit.to_relative(P))  # a, b are frame offsets with unit radii
    u = rel[:, 0]
    t = np.clip((u + 1) / 2, 0, 1)
    key_t = np.linspace(0, 1, n_keys)
    keys = []
    for k, tk in enumerate(key_t):  # radii lerp between keys: cover the two adjacent intervals
        w = 1.0 / (n_keys - 1)
        sel = np.abs(t - tk) <= w * 1.0001
        y, z = (rel[sel, 1], rel[sel, 2]) if sel.any() else (np.zeros(1), np.zeros(1))
        ry, rz = ellipse_radii(y, z, min_radius)
        keys.append({"t": float(tk), "radii": [ry * (1 + margin), rz * (1 + margin)]})
    d = {**base, "keys": keys}
    gc = GeneralizedCylinder.from_dict(d)
    rel = np.asarray(gc.to_relative(P))
    caps = []
    for end, past in ((0, rel[:, 0] < -1), (1, rel[:, 0] > 1)):
        if not past.any():
            caps.append(min_radius)
            continue
        unit_rel = np.asarray(unit.to_relative(P[past]))
        along = np.abs(unit_rel[:, 0]) - 1  # cap distance with unit caps
        slack = np.sqrt(np.clip(1 - rel[past, 1] ** 2 - rel[past, 2] ** 2, 0.05, None))
        caps.append(float((along / slack).max()) * (1 + margin) + min_radius)
    d["caps"] = caps
    for _ in range(40):
        gc = GeneralizedCylinder.from_dict(d)
        if np.asarray(gc.contains(P)).all():
            return gc
        d["keys"] = [{**k, "radii": [r * 1.05 for r in k["radii"]]} for k in d["keys"]]
        d["caps"] = [c * 1.05 for c in d["caps"]]
    raise DataError(f"could not enclose the points of '{name}'", gc=name,
                    fix="annotate this part by hand")
