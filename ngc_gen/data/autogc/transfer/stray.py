"""A missing end part (a tail the skeleton has no branch for) stands in over the surface that
the found parts leave unexplained where the part would be.

The template says where a tail sits relative to the body, but tails differ: a stub lying along
the back's line, one hanging down the rump, one sticking out. A stand-in placed by the
template alone (from its start toward its end) misses all three. The surface itself says
where the tail is: beyond the part's template start along the front-back axis (behind the
rump), near the mid-plane, above the found legs' feet, and outside every GC already found
(the torso and legs do not explain it). When that surface is there (at least MIN_SHARE of
the samples), the stand-in runs from its attachment through the surface's middle to its far
end along the surface's principal direction, fitted to and grown over that surface;
otherwise (a tailless rear, whose surface the torso and legs explain) it returns None and the
caller keeps its template stub.
"""
from __future__ import annotations

import numpy as np

from ngc_gen.data.autogc.coverage import grow_to_cover, rho_matrix
from ngc_gen.data.autogc.template import TemplateGC
from ngc_gen.geometry import GeneralizedCylinder

from .leg_order import reaches_down

MID_BAND = 0.5     # body units left/right of the part's template start: near the mid-plane
MIN_SHARE = 0.002  # the unexplained surface stands in when it holds this share of the samples
CLEAR = 1.0        # a sample is unexplained when outside every found GC (rho > CLEAR)
LOW = 0.25         # the found legs' lower quarter (the feet) is left out: a foot is no tail


def stray_surface(pl, tgc: TemplateGC, surface_body: np.ndarray) -> np.ndarray:
    """(k,) indices of the surface samples where the missing `tgc` would be that no found GC
    holds: beyond its template start along the front-back axis, toward its end's side of the
    body, within MID_BAND of its start across the mid-plane, above the found legs' feet.
    `pl`: the assembly's Placing (passed in, not imported: assemble imports this module)."""
    start, end = (np.asarray(tgc.place[k], np.float64) for k in ("start", "end"))
    back = np.sign(end[0] - start[0]) or -1.0
    near = np.flatnonzero(((surface_body[:, 0] - start[0]) * back > 0.0)
                          & (np.abs(surface_body[:, 1] - start[1]) <= MID_BAND)
                          & (surface_body[:, 2] > _feet_level(pl)))
    found = [g for n, g in pl.gcs.items() if n not in pl.missing]
    if not len(near) or not found:
        return near
    rho, _ = rho_matrix(found, pl.surface[near])
    return near[rho.min(axis=0) > CLEAR]


def _feet_level(pl) -> float:
    """The body height (up, body units) below which the found legs' lower LOW of their length
    lies: the feet, whose soles and inner sides the leg GCs may leave out; -inf without legs."""
    ends = [pl.body.to_body(_curve_ends(g)) for n, g in pl.gcs.items()
            if n not in pl.missing and reaches_down(pl.template.gc(n).place)]
    if not ends:
        return -np.inf
    return float(np.mean([e[1, 2] + LOW * (e[0, 2] - e[1, 2]) for e in ends]))


def _curve_ends(gc: GeneralizedCylinder) -> np.ndarray:
    return np.asarray(gc.to_world(np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])))


def stray_stand_in(pl, tgc: TemplateGC, start: np.ndarray,
                   surface_body: np.ndarray) -> GeneralizedCylinder | None:
    """The missing `tgc` from `start` (its attachment, world) over the unexplained surface where
    it would be (module docstring); None when there is too little of it."""
    own = pl.surface[stray_surface(pl, tgc, surface_body)]
    if len(own) < MIN_SHARE * len(pl.surface):
        return None
    mid = own.mean(axis=0)
    _, _, vt = np.linalg.svd(own - mid, full_matrices=False)
    d = vt[0] if vt[0] @ (mid - start) >= 0.0 else -vt[0]   # away from the attachment
    tip = mid + d * float(((own - mid) @ d).max())
    if not np.linalg.norm(tip - start) > pl.floor:
        return None
    s = np.linspace(0.0, 1.0, 16)[:, None]
    poly = np.vstack([start + s[:-1] * (mid - start), mid + s * (tip - mid)])
    return grow_to_cover([pl.gc(tgc, poly, own)], own)[0]
