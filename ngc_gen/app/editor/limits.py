"""What the editor refuses beyond what the edit ops themselves check.

The ops accept any positive radius, any finite twist and any control point that leaves the curve
regular; an interactive drag can reach values that are legal but useless (a radius of a
micrometre, a twist of 10,000 degrees, a control point on top of its neighbour, a GC dragged out
of the extraction box, where marching cubes cuts it open). Only GCs the interaction changed are
checked, so a shape that starts outside a limit can still be edited elsewhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.geometry import GeneralizedCylinder


@dataclass(frozen=True)
class Limits:
    """min_radius: smallest key radius (world units); max_twist: largest |twist| at a key
    (degrees); min_point_gap: smallest distance between consecutive control points; bound:
    the extraction box [-bound, bound]^3 a changed GC must stay inside."""

    min_radius: float
    max_twist: float
    min_point_gap: float
    bound: float


def changed_gcs(before: list[GeneralizedCylinder], after: list[GeneralizedCylinder]
                ) -> list[tuple[GeneralizedCylinder, GeneralizedCylinder]]:
    """(before, after) pairs of the GCs whose parameters an edit changed (same index)."""
    return [(b, a) for b, a in zip(before, after) if a is not b and a.to_dict() != b.to_dict()]


def _gap_violation(before: GeneralizedCylinder, after: GeneralizedCylinder,
                   limits: Limits) -> str | None:
    """A control point moved too close to its neighbour: a gap between consecutive points that
    shrank below `min_point_gap` (curves rebuilt with other points, as a stretch does, are
    the op's own business)."""
    p0, p1 = (np.asarray(g.curve.points, dtype=np.float64) for g in (before, after))
    if p0.shape != p1.shape:
        return None
    g0, g1 = (np.linalg.norm(np.diff(p, axis=0), axis=1) for p in (p0, p1))
    bad = (g1 < limits.min_point_gap) & (g1 < g0)
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    return (f"GC '{after.name}': control points {i} and {i + 1} are {g1[i]:.4g} apart, closer "
            f"than {limits.min_point_gap:g}; move the point away from its neighbour")


def violation(before: GeneralizedCylinder, gc: GeneralizedCylinder,
              limits: Limits) -> str | None:
    """Why `gc` (edited from `before`) breaks a limit (one sentence naming the GC and what to
    do), or None."""
    radii = np.array([k.radii for k in gc.keys], dtype=np.float64)
    if radii.min() < limits.min_radius:
        k = int(np.argmin(radii.min(1)))
        return (f"GC '{gc.name}': radius {radii.min():.4g} at key t = {gc.keys[k].t:.3g} is "
                f"below the editor's minimum {limits.min_radius:g}; keep the radius larger")
    twist = np.array([k.twist for k in gc.keys], dtype=np.float64)
    if np.abs(twist).max() > limits.max_twist:
        k = int(np.argmax(np.abs(twist)))
        return (f"GC '{gc.name}': twist {twist[k]:.1f} deg at key t = {gc.keys[k].t:.3g} exceeds "
                f"+-{limits.max_twist:g} deg; use a smaller twist")
    why = _gap_violation(before, gc, limits)
    if why is not None:
        return why
    lo, hi = gc.bounds()
    if lo.min() < -limits.bound or hi.max() > limits.bound:
        return (f"GC '{gc.name}' leaves the extraction box [-{limits.bound:g}, "
                f"{limits.bound:g}]^3 (its bounds reach {max(-lo.min(), hi.max()):.3g}); keep it "
                f"inside")
    return None


def check(before: list[GeneralizedCylinder], after: list[GeneralizedCylinder],
          limits: Limits) -> str | None:
    """The first limit an edit before -> after breaks on a GC it changed, or None."""
    for old, new in changed_gcs(before, after):
        why = violation(old, new, limits)
        if why is not None:
            return why
    return None
