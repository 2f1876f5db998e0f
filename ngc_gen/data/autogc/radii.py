"""Cross-section fits shared by every GC builder: principal axes of a point set and the
smallest axis-aligned ellipse that holds a slice of points."""

from __future__ import annotations

import numpy as np


def principal_axes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean (3,) and principal axes (3, 3), rows by decreasing variance, right-handed, each
    with its largest component positive so the result does not depend on SVD sign choices."""
    center = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - center, full_matrices=False)
    axes = vt * np.sign(vt[np.arange(3), np.argmax(np.abs(vt), axis=1)])[:, None]
    axes[2] = np.cross(axes[0], axes[1])
    return center, axes


def ellipse_radii(y: np.ndarray, z: np.ndarray, floor: float, n: int = 64,
                  q: float = 1.0) -> tuple[float, float]:
    """Smallest-area axis-aligned ellipse (r_y, r_z), centred at 0, that holds all (y, z), or
    with q < 1 the share q of them (a few stray points: a horn's base in a head's slice, do
    not size it).

    For an aspect k = r_z/r_y the tight r_y is the q-quantile of sqrt(y^2 + (z/k)^2); scan k
    on a log grid around the extent ratio (a loop over n aspects, each vectorised over
    points)."""
    def held(v):
        return float(v.max()) if q >= 1.0 else float(np.quantile(v, q))

    ym, zm = max(held(np.abs(y)), floor), max(held(np.abs(z)), floor)
    best = (np.inf, ym * np.sqrt(2.0), zm * np.sqrt(2.0))  # the box's circumscribed ellipse
    for k in (zm / ym) * np.geomspace(1 / 8, 8, n):
        ry = max(held(np.sqrt(y * y + (z / k) ** 2)), floor, floor / k)
        if ry * ry * k < best[0]:
            best = (ry * ry * k, ry, ry * k)
    return best[1], best[2]
