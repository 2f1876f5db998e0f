"""How well a set of GCs covers a surface, and local growth until it does (docs/autogc.md).

rho(q, gc) = sqrt(max(|u|-1, 0)^2 + a^2 + b^2) of a point's relative coordinates is <= 1 inside
the GC, and scaling the radii of the keys around the point's t (tube) or its end's cap (past an
end) by rho moves it onto the boundary: t, u along the tube and the frames do not depend on the
radii, so one growth round per GC is exact up to rounding.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ngc_gen.geometry import GeneralizedCylinder

from ngc_gen.data.mesh.sampling import gc_membership


def rho_matrix(gcs: Sequence[GeneralizedCylinder], points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(G, N) rho of every point in every GC and (G, N) its u."""
    rho = np.zeros((len(gcs), len(points)))
    u = np.zeros((len(gcs), len(points)))
    for g, gc in enumerate(gcs):
        rel = np.asarray(gc.to_relative(points))
        rho[g] = np.sqrt(GeneralizedCylinder.relative_measure(rel))
        u[g] = rel[:, 0]
    return rho, u


def coverage_stats(gcs: Sequence[GeneralizedCylinder], points: np.ndarray) -> dict:
    """{coverage: share of points inside some GC, overlap: share of points inside two or more,
    per_gc: (G,) share of points inside each GC}."""
    pp, pg, _ = gc_membership(points, gcs)
    count = np.bincount(pp, minlength=len(points))
    return {"coverage": float((count >= 1).mean()), "overlap": float((count >= 2).mean()),
            "per_gc": np.bincount(pg, minlength=len(gcs)) / max(len(points), 1)}


def _grown(gc: GeneralizedCylinder, rel: np.ndarray, rho: np.ndarray, slack: float) -> GeneralizedCylinder:
    """gc with the keys around each point's t (tube points) or the cap of its end (past an end)
    grown so every given point (rel (P, 3), rho (P,) > 1) lies inside with ``slack``."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    grow = np.ones(len(key_t))
    caps = np.array(d["caps"], dtype=np.float64)
    u = rel[:, 0]
    tube = np.abs(u) <= 1.0
    if tube.any():
        t = (u[tube] + 1.0) / 2.0
        hi = np.clip(np.searchsorted(key_t, t, side="left"), 0, len(key_t) - 1)
        lo = np.clip(hi - 1, 0, len(key_t) - 1)
        f = rho[tube] * slack
        np.maximum.at(grow, hi, f)
        np.maximum.at(grow, lo, f)
    for end, past in ((0, u < -1.0), (1, u > 1.0)):
        if not past.any():
            continue
        side = rel[past, 1] ** 2 + rel[past, 2] ** 2
        e = np.abs(u[past]) - 1.0
        # a point near the axis: lengthen the cap only; else widen the end section and the cap
        near = side <= 0.8
        cap_f = np.where(near, e / np.sqrt(np.clip(1.0 - side, 1e-6, None)) * slack, rho[past] * slack)
        caps[end] *= max(1.0, float(cap_f.max()))
        if (~near).any():
            k = 0 if end == 0 else len(key_t) - 1
            grow[k] = max(grow[k], float(rho[past][~near].max()) * slack)
    d["keys"] = [{**k, "radii": [r * g for r in k["radii"]]} for k, g in zip(d["keys"], grow)]
    d["caps"] = caps.tolist()
    return GeneralizedCylinder.from_dict(d)


def grow_to_cover(gcs: list[GeneralizedCylinder], points: np.ndarray, slack: float = 1.02,
                  max_rounds: int = 8, owner: np.ndarray | None = None,
                  groups: np.ndarray | None = None) -> list[GeneralizedCylinder]:
    """GCs grown locally until every point (N, 3) is inside one: each uncovered point is given
    to the GC it is relatively nearest to (smallest rho), among the GCs of its ``owner``'s
    group if ``owner`` (N,) and ``groups`` (G,) are given (a piece of a mesh never grows to
    hold another piece), and that GC's keys or cap around it grow. A last resort after
    ``max_rounds`` scales whole GCs."""
    gcs = list(gcs)
    for round_ in range(max_rounds + 10):
        pp, _, _ = gc_membership(points, gcs)
        missed = np.bincount(pp, minlength=len(points)) == 0
        if not missed.any():
            return gcs
        q = points[missed]
        rho, _ = rho_matrix(gcs, q)
        if owner is not None and groups is not None:
            rho = np.where(groups[:, None] == groups[owner[missed]][None, :], rho, np.inf)
        given = rho.argmin(axis=0)
        for g in np.unique(given):
            mine = given == g
            if round_ < max_rounds:
                rel = np.asarray(gcs[g].to_relative(q[mine]))
                gcs[g] = _grown(gcs[g], rel, rho[g, mine], slack)
            else:  # uniform growth: always terminates, rarely needed
                d = gcs[g].to_dict()
                d["keys"] = [{**k, "radii": [r * 1.1 for r in k["radii"]]} for k in d["keys"]]
                d["caps"] = [c * 1.1 for c in d["caps"]]
                gcs[g] = GeneralizedCylinder.from_dict(d)
    return gcs
