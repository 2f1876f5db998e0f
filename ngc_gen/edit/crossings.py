"""Which parts an edit drives a limb through: a swing that pushes a leg into the torso or
through the other leg gives a shape no animal has, and the edit program should say so.

For each GC the edit changed, points along its curve (past its attachment, t >= `start`) that
lie in the core of another GC after the edit (relative radius below `core`, so touching or
grazing a neighbour's shell does not count) and did not before, at the same t. The same test on
the unedited shape finds nothing, whatever overlaps it had."""
from __future__ import annotations

import numpy as np

from ngc_gen.geometry import GeneralizedCylinder

from .ops import curve_points_at

# curve points from this t on (a limb starts inside its parent), and a relative radius
# (1: the GC's boundary) inside which a point is in another part's core
START_T, CORE = 0.25, 0.6


def _in_core(gc: GeneralizedCylinder, points: np.ndarray, core: float) -> np.ndarray:
    _, measure = gc.relative_inside(points)
    return measure <= core * core


def crossings(before: list[GeneralizedCylinder], after: list[GeneralizedCylinder],
              n: int = 24, start: float = START_T, core: float = CORE) -> dict[str, list[str]]:
    """{changed GC name: [names of GCs its curve now passes through]} (only GCs that cross
    something). before, after: the same GCs in the same order, before and after an edit."""
    t = np.linspace(start, 1.0, n)
    out = {}
    for b, a in zip(before, after):
        if b.to_dict() == a.to_dict():
            continue
        pb, pa = curve_points_at(b, t), curve_points_at(a, t)
        hit = [o.name for o in after if o.name != a.name
               and (_in_core(o, pa, core) & ~_in_core(before[[g.name for g in before]
                                                              .index(o.name)], pb, core)).any()]
        if hit:
            out[a.name] = hit
    return out


def crossing_warning(found: dict[str, list[str]]) -> str | None:
    """One line naming the GCs, or None."""
    if not found:
        return None
    parts = "; ".join(f"{k} through {', '.join(v)}" for k, v in found.items())
    return (f"the edit drives {parts} (its curve now runs inside them): check the axis and the "
            f"angle, a body direction (forward, up, left) follows the shape's frame")
