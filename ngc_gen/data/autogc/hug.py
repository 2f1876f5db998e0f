"""GCs that hug the surface: radii from a part's own surface, coverage by the cheapest local
growth (docs/transfer.md).

``hug_radii``: each key's radii are the smallest ellipse that holds the share q of the GC's
own samples nearest that key and within the part's thickness (THICK x their median distance
from the curve): not the largest over both intervals around the key, which sizes a tapering
leg's every key by its thickest end, nor a horn standing on the head's slice.

``recentred``: the section is an ellipse centred on the curve, so a curve off the middle of
its part (a skeleton's path nearer the back of a thigh, the rump's end) widens it by twice the
offset. The curve moves to the middle of its own samples' extent, per key or per finer bin;
``hugged`` keeps whichever of the three curves (as found, per key, per bin) holds all its own
samples for the least volume (a head's horns can make the moved curve worse).

``coverage.grow_to_cover`` gives an uncovered point to the GC it is relatively nearest to and
scales both radii of the keys around it by the point's relative distance: a horn on a head
grows the whole head as wide as the horn is long, a tuft of tail hair goes to the thicker leg
beside it. Here each uncovered point goes to the GC that holds it for the least added volume,
and that GC grows only where and how the point needs:

- in the tube, the smallest-area ellipse through the point: one radius grows when the point
  lies along that axis (a horn above the head: r_z only), both when it lies between them;
  that growth is shared by the two keys around the point in proportion to how near each is
  (a point at a key grows that key alone);
- past an end, the cap lengthens for a point near the axis, the end's section widens (as
  above) for one beside it.

A point's cost in a GC is the volume the growth adds there (cross-section area x the length
its keys answer for, plus the cap's half-ellipsoid), so a thin tail takes its own hair and a
head covers an ear with a bump of one radius; in the GC the point belongs to (``owner``) it
counts OWN_SHARE of that. Rounds repeat until every point is inside; a
last resort after ``max_rounds`` scales whole GCs (as ``grow_to_cover``).

``tighten`` (its own module) then fits each GC's radii and caps to the least volume that
still holds its samples; ``centred_on_held`` last moves each curve, ends too, to the middle
of everything its GC holds (what it holds on one side only swells the centred ellipse as far
on the other) where that holds it all for less volume.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.radii import ellipse_radii
from ngc_gen.data.autogc.tighten import gc_volume, tighten
from ngc_gen.data.mesh.sampling import gc_membership
from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis

NEAR_AXIS = 0.8  # past an end, a point with a^2 + b^2 below this lengthens the cap only
OWN_SHARE = 0.25  # an uncovered sample's cost in the GC it belongs to counts this much: a part
                  # holds its own surface (a mane stays the neck's) unless another GC holds it
                  # for a quarter of the volume
MIN_SLICE = 10    # a key whose slice has fewer own samples keeps its radii
THICK = 1.7       # a slice's sample farther from the curve than this x the slice's median is not
                  # the part's body (a horn, an ear): left to coverage (1.4 to 2.0 give the same
                  # outside volume on the turned 0 A.D. animals; 1.7 the best purity)
BINS = 9          # ``hugged`` also tries the curve centred on this many bins along it


def min_area_factors(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(f_y, f_z) >= 1 of least product f_y f_z with (a/f_y)^2 + (b/f_z)^2 <= 1 (P,): how much
    an ellipse's two radii must grow to hold a point at relative (a, b), at least added area.

    Candidates: one radius alone (the other kept; needs the other coordinate inside 1), or both
    at sqrt(2) |a|, sqrt(2) |b| (the unconstrained optimum, when both are >= 1)."""
    a, b = np.abs(a), np.abs(b)
    big = np.inf
    # r_z alone: f_y = 1, f_z = b / sqrt(1 - a^2)
    z_only = np.where(a < 1.0, b / np.sqrt(np.clip(1.0 - a * a, 1e-12, None)), big)
    y_only = np.where(b < 1.0, a / np.sqrt(np.clip(1.0 - b * b, 1e-12, None)), big)
    both_ok = (a >= 2 ** -0.5) & (b >= 2 ** -0.5)
    both = np.where(both_ok, 2.0 * a * b, big)
    pick = np.argmin(np.stack([z_only, y_only, both]), axis=0)
    fy = np.where(pick == 0, 1.0, np.where(pick == 1, y_only, np.sqrt(2.0) * a))
    fz = np.where(pick == 0, z_only, np.where(pick == 1, 1.0, np.sqrt(2.0) * b))
    return np.maximum(fy, 1.0), np.maximum(fz, 1.0)


def hug_radii(gc: GeneralizedCylinder, own: np.ndarray, q: float, margin: float,
              floor: float) -> GeneralizedCylinder:
    """gc with each key's radii the smallest ellipse holding the share `q` of its own samples
    (M, 3) in the tube nearest that key and within THICK x their median distance from the
    curve, grown by `margin` (module docstring)."""
    if len(own) < MIN_SLICE:
        return gc
    d = gc.to_dict()
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    _, y, z, nearest, body = _slices(gc, own)
    for k in np.unique(nearest[body]):
        sel = body & (nearest == k)
        radii[k] = np.asarray(ellipse_radii(y[sel], z[sel], floor, q=q)) * (1.0 + margin)
    d["keys"] = [{**k, "radii": [float(r) for r in rr]} for k, rr in zip(d["keys"], radii)]
    return GeneralizedCylinder.from_dict(d)


def _slices(gc: GeneralizedCylinder, own: np.ndarray, at: np.ndarray | None = None,
            thick: float = THICK):
    """The GC's own samples (M, 3) in its tube as (t, y, z, nearest key, body): arc t, offsets
    y, z from the curve in its frame, the key each is nearest and whether it lies within
    `thick` x its slice's median distance from the curve (its key's slice has MIN_SLICE such)."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    rel = np.asarray(gc.to_relative(own)) if len(own) else np.zeros((0, 3))
    rel = rel[np.abs(rel[:, 0]) <= 1.0]
    t = (rel[:, 0] + 1.0) / 2.0
    y = rel[:, 1] * np.interp(t, key_t, radii[:, 0])
    z = rel[:, 2] * np.interp(t, key_t, radii[:, 1])
    r = np.hypot(y, z)
    at = key_t if at is None else at
    nearest = np.argmin(np.abs(t[:, None] - at[None, :]), axis=1)
    count = np.bincount(nearest, minlength=len(at))
    med = np.array([np.median(r[nearest == k]) if count[k] else 0.0 for k in range(len(at))])
    body = (count[nearest] >= MIN_SLICE) & (r <= thick * med[nearest])
    body &= np.bincount(nearest[body], minlength=len(at))[nearest] >= MIN_SLICE
    return t, y, z, nearest, body


def recentred(gc: GeneralizedCylinder, own: np.ndarray, bins: int = 0,
              thick: float = THICK, ends: bool = False) -> GeneralizedCylinder:
    """gc with its curve moved to the middle of its own body samples (M, 3) (the midpoint of
    their extent in each frame axis; within `thick` as in ``hug_radii``, inf: all of them)
    at each key, or at `bins` points evenly along it, lerped between: a curve off the middle
    of its part makes the centred ellipse twice the offset wider. The ends stay (where the part attaches and ends,
    as the template calibrates them); the moved centre line is refitted as a Bezier of the
    same degree; a slice without enough samples follows its neighbours."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    at = np.linspace(0.0, 1.0, bins) if bins else key_t
    t, y, z, nearest, body = _slices(gc, own, at, thick)
    if not body.any() or d["curve"]["type"] != "bezier":
        return gc
    K = len(at)
    shift, have = np.zeros((K, 2)), np.bincount(nearest[body], minlength=K) > 0
    for j, v in enumerate((y[body], z[body])):
        lo, hi = np.full(K, np.inf), np.full(K, -np.inf)
        np.minimum.at(lo, nearest[body], v)
        np.maximum.at(hi, nearest[body], v)
        shift[have, j] = (lo[have] + hi[have]) / 2.0
    inner = have & (at > 0.0) & (at < 1.0)   # the ends stay: where the part attaches and ends
    if K < 3 or not inner.any():               # (a calibrated template's start_at, end_at)
        return gc
    s = np.linspace(0.0, 1.0, 64)
    r_s = np.stack([np.interp(s, key_t, radii[:, j]) for j in range(2)], 1)
    if ends:  # (`ends`: they move too, each with its nearest slice)
        c_s = np.stack([np.interp(s, at[have], shift[have, j]) for j in range(2)], 1)
    else:
        c_s = np.stack([np.interp(s, np.r_[0.0, at[inner], 1.0], np.r_[0.0, shift[inner, j], 0.0])
                        for j in range(2)], 1)
    line = np.asarray(gc.to_world(np.column_stack([2.0 * s - 1.0, c_s / r_s])), dtype=np.float64)
    d["curve"] = {"type": "bezier",
                  "points": _bezier_through(line, len(d["curve"]["points"]) - 1).tolist()}
    return GeneralizedCylinder.from_dict(d)


def hugged(gc: GeneralizedCylinder, own: np.ndarray, q: float, margin: float,
           floor: float) -> GeneralizedCylinder:
    """gc sized to its own samples (M, 3) by ``hug_radii`` on the curve as found, recentred per
    key, or recentred per BINS bins (twice each: the slices move with the curve), whichever
    holds all of `own` (grown by ``hug_to_cover``) for the least volume."""
    start = hug_radii(gc, own, q, margin, floor)
    options = [start]
    for bins in (0, BINS):
        moved = start
        for _ in range(2):
            moved = hug_radii(recentred(moved, own, bins), own, q, margin, floor)
        options.append(moved)
    held = [gc_volume(hug_to_cover([g], own)[0]) if len(own) else gc_volume(g) for g in options]
    return options[int(np.argmin(held))]


def centred_on_held(gcs: list[GeneralizedCylinder], points: np.ndarray,
                    fixed: set[int] = frozenset()) -> list[GeneralizedCylinder]:
    """Each GC (but those `fixed`) with its curve, ends included, moved to the middle of
    everything it holds of `points` (N, 3) at each key, if that holds all of it (grown to,
    then tightened) for less volume: a section is an ellipse centred on the curve, so what a
    GC holds on one side only (the legs' tops under a torso, a horn or an ear on a head, a
    hump) widens it as much on the other side, where there is nothing. Every sample a GC held
    it still holds, so no part's share of its surface falls."""
    gcs = list(gcs)
    pp, pg, _ = gc_membership(points, gcs)
    for g, gc in enumerate(gcs):
        held = points[pp[pg == g]]
        if g in fixed or len(held) < MIN_SLICE:
            continue
        moved = tighten(hug_to_cover([recentred(gc, held, thick=np.inf, ends=True)], held), held)[0]
        if gc_volume(moved) < gc_volume(gc):
            gcs[g] = moved
    return gcs


def _bezier_through(P: np.ndarray, degree: int) -> np.ndarray:
    """Control points (degree+1, 3) of the least-squares Bezier through P (k, 3) by chord
    length, its ends on P's."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    B = bernstein_basis(degree, arc / max(arc[-1], 1e-12))
    ctrl = np.empty((degree + 1, 3))
    ctrl[0], ctrl[-1] = P[0], P[-1]
    if degree > 1:
        rhs = P - B[:, :1] * ctrl[0] - B[:, -1:] * ctrl[-1]
        ctrl[1:-1] = np.linalg.lstsq(B[:, 1:-1], rhs, rcond=None)[0]
    return ctrl


@dataclass
class Plan:
    """How one GC grows to hold each of P points: per point the factor of each key's radii
    (P, K, 2) (1: unchanged), of each cap (P, 2), and the volume that adds (P,)."""

    keys: np.ndarray
    caps: np.ndarray
    cost: np.ndarray


def _key_share(key_t: np.ndarray, t: np.ndarray, radii: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(P, K, 2) key factors that grow the lerped radii at t (P,) by F (P, 2): the growth
    shared by the two keys around t in proportion to their lerp weights (least squares: a
    point at a key grows that key alone)."""
    K, P = len(key_t), len(t)
    out = np.ones((P, K, 2))
    if K == 1:
        out[:, 0] = F
        return out
    hi = np.clip(np.searchsorted(key_t, t, side="right"), 1, K - 1)
    lo = hi - 1
    w = np.clip((t - key_t[lo]) / (key_t[hi] - key_t[lo]), 0.0, 1.0)[:, None]
    r_lo, r_hi = radii[lo], radii[hi]
    r_t = (1 - w) * r_lo + w * r_hi
    c = r_t / ((1 - w) ** 2 * r_lo + w ** 2 * r_hi)
    rows = np.arange(P)
    out[rows, lo] = 1.0 + (F - 1.0) * (1 - w) * c
    out[rows, hi] = np.maximum(out[rows, hi], 1.0 + (F - 1.0) * w * c)
    return out


def plan(gc: GeneralizedCylinder, rel: np.ndarray, slack: float) -> Plan:
    """The cheapest growth of `gc` that puts each point (relative coordinates rel (P, 3) in
    it) inside with `slack` (module docstring)."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    caps = np.array(d["caps"], dtype=np.float64)
    u, a, b = rel[:, 0], rel[:, 1] * slack, rel[:, 2] * slack
    t = np.clip((u + 1.0) / 2.0, 0.0, 1.0)
    e = np.clip(np.abs(u) - 1.0, 0.0, None) * slack
    end = np.where(u < -1.0, 0, np.where(u > 1.0, 1, -1))
    side = a * a + b * b
    # past an end beside the axis: the cap takes e up to half of the budget, the section the rest
    cap_f = np.where(side <= NEAR_AXIS, e / np.sqrt(np.clip(1.0 - side, 1e-6, None)),
                     np.maximum(1.0, e * np.sqrt(2.0)))
    cap_f = np.where(end >= 0, np.maximum(cap_f, 1.0), 1.0)
    rest = np.where(end >= 0, np.clip(1.0 - (e / cap_f) ** 2, 1e-6, None), 1.0)
    beside = (end < 0) | (side > NEAR_AXIS)
    F = np.ones((len(u), 2))
    fy, fz = min_area_factors(a[beside] / np.sqrt(rest[beside]), b[beside] / np.sqrt(rest[beside]))
    F[beside] = np.stack([fy, fz], 1)
    keys = _key_share(key_t, t, radii, F)
    capf = np.ones((len(u), 2))
    rows = np.flatnonzero(end >= 0)
    capf[rows, end[rows]] = cap_f[rows]
    return Plan(keys=keys, caps=capf, cost=_added_volume(gc.length, key_t, radii, caps, keys, capf))


def _added_volume(length: float, key_t: np.ndarray, radii: np.ndarray, caps: np.ndarray,
                  keys: np.ndarray, capf: np.ndarray) -> np.ndarray:
    """(P,) volume a plan adds: each key's area change over the length its hat answers for
    (half of each neighbouring interval), each cap's half-ellipsoid change."""
    span = np.diff(key_t) if len(key_t) > 1 else np.ones(0)
    hat = length * (np.r_[span, 0.0] + np.r_[0.0, span]) / 2.0 if len(key_t) > 1 \
        else np.array([length])
    area = np.pi * radii.prod(1)                                        # (K,)
    tube = ((keys.prod(2) - 1.0) * area * hat).sum(1)
    end_area = np.pi * np.stack([radii[0].prod() * keys[:, 0].prod(1),
                                 radii[-1].prod() * keys[:, -1].prod(1)], 1)  # (P, 2)
    cap = (2.0 / 3.0) * (end_area * caps * capf - np.pi * np.array([radii[0].prod(),
                                                                    radii[-1].prod()]) * caps)
    return tube + cap.sum(1)


def _apply(gc: GeneralizedCylinder, p: Plan) -> GeneralizedCylinder:
    """gc with every key and cap grown by the largest factor its points ask for."""
    d = gc.to_dict()
    kf, cf = p.keys.max(0), p.caps.max(0)
    d["keys"] = [{**k, "radii": [r * f for r, f in zip(k["radii"], g)]} for k, g in zip(d["keys"], kf)]
    d["caps"] = [c * f for c, f in zip(d["caps"], cf)]
    return GeneralizedCylinder.from_dict(d)


def hug_to_cover(gcs: list[GeneralizedCylinder], points: np.ndarray, slack: float = 1.02,
                 max_rounds: int = 8, owner: np.ndarray | None = None,
                 own_share: float = OWN_SHARE) -> list[GeneralizedCylinder]:
    """GCs grown until every point (N, 3) is inside one, each uncovered point by the GC that
    holds it for the least added volume, grown only where and how it needs (module
    docstring). owner (N,): the GC each point belongs to (-1: none), whose cost counts
    `own_share` x (below 1: a part prefers to hold its own surface)."""
    gcs = list(gcs)
    missed = np.arange(len(points))
    for round_ in range(max_rounds + 10):  # GCs only grow: a sample inside stays inside
        pp, _, _ = gc_membership(points[missed], gcs)
        missed = missed[np.bincount(pp, minlength=len(missed)) == 0]
        if not len(missed):
            return gcs
        q = points[missed]
        if round_ >= max_rounds:  # uniform growth: always terminates, rarely needed
            rho, _ = rho_matrix(gcs, q)
            for g in np.unique(rho.argmin(0)):
                d = gcs[g].to_dict()
                d["keys"] = [{**k, "radii": [r * 1.1 for r in k["radii"]]} for k in d["keys"]]
                d["caps"] = [c * 1.1 for c in d["caps"]]
                gcs[g] = GeneralizedCylinder.from_dict(d)
            continue
        plans = [plan(gc, np.asarray(gc.to_relative(q)), slack) for gc in gcs]
        cost = np.stack([p.cost for p in plans])
        if owner is not None:
            mine = owner[missed][None, :] == np.arange(len(gcs))[:, None]
            cost = np.where(mine, cost * own_share, cost)
        given = cost.argmin(0)
        for g in np.unique(given):
            mine = given == g
            gcs[g] = _apply(gcs[g], Plan(plans[g].keys[mine], plans[g].caps[mine], plans[g].cost[mine]))
    return gcs
