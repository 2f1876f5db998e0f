"""GCs that hug the surface: radii from a part's own surface, coverage by the cheapest local
growth (docs/transfer.md).

``hug_radii``: each key's radii are the smallest ellipse that holds the share q of the GC's
own samples nearest that key and within the part's thickness (THICK x their median distance
from the curve): not the largest over both intervals around the key, which sizes a tapering
leg's every key by its thickest end, nor a horn standing on the head's slice.

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

``tighten`` then shrinks each key's radii, one GC after another, as far as the samples only
that GC holds allow: growth point by point overshoots (the largest factor any point asks
for), and where another GC holds a sample this one need not.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.radii import ellipse_radii
from ngc_gen.data.mesh.sampling import gc_membership
from ngc_gen.geometry import GeneralizedCylinder

NEAR_AXIS = 0.8  # past an end, a point with a^2 + b^2 below this lengthens the cap only
OWN_SHARE = 0.25  # an uncovered sample's cost in the GC it belongs to counts this much: a part
                  # holds its own surface (a mane stays the neck's) unless another GC holds it
                  # for a quarter of the volume
MIN_SLICE = 10    # a key whose slice has fewer own samples keeps its radii
THICK = 1.4       # a slice's sample farther from the curve than this x the slice's median is not
                  # the part's body (a horn, an ear): left to coverage


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
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    if len(own) < MIN_SLICE:
        return gc
    rel = np.asarray(gc.to_relative(own))
    tube = np.abs(rel[:, 0]) <= 1.0
    t = (rel[tube, 0] + 1.0) / 2.0
    y = rel[tube, 1] * np.interp(t, key_t, radii[:, 0])  # offsets from the curve, in its frame
    z = rel[tube, 2] * np.interp(t, key_t, radii[:, 1])
    r = np.hypot(y, z)
    nearest = np.argmin(np.abs(t[:, None] - key_t[None, :]), axis=1)
    for k in range(len(key_t)):
        sel = nearest == k
        if sel.sum() >= MIN_SLICE:
            sel &= r <= THICK * np.median(r[sel])
        if sel.sum() >= MIN_SLICE:
            radii[k] = np.asarray(ellipse_radii(y[sel], z[sel], floor, q=q)) * (1.0 + margin)
    d["keys"] = [{**k, "radii": [float(r) for r in rr]} for k, rr in zip(d["keys"], radii)]
    return GeneralizedCylinder.from_dict(d)


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


SHRINK = np.geomspace(0.5, 1.0, 13)  # the factors `tighten` tries a key's radius at


def _measure(key_t, radii, caps, t, y, z, past, end) -> np.ndarray:
    """(..., P) relative measure of samples at arc t (P,) with offsets y, z (P,) from the curve
    in its frame and `past` (P,) beyond end `end` (0 / 1; past 0 in the tube), for radii
    (..., K, 2) and caps (2,)."""
    r = np.stack([np.stack([np.interp(t, key_t, rr[..., j]) for j in range(2)], -1)
                  for rr in radii.reshape(-1, *radii.shape[-2:])]).reshape(*radii.shape[:-2], len(t), 2)
    e = past / caps[end]
    return e * e + (y / r[..., 0]) ** 2 + (z / r[..., 1]) ** 2


def tighten(gcs: list[GeneralizedCylinder], points: np.ndarray, owner: np.ndarray | None = None,
            slack: float = 1.02, fixed: set[int] = frozenset()) -> list[GeneralizedCylinder]:
    """Each GC's key radii shrunk (to SHRINK factors, twice over its keys) while every sample
    (N, 3) it alone holds, and every one of its own (owner (N,): the GC each sample belongs
    to, -1: none), stays inside with `slack` (module docstring); the GCs `fixed` are kept."""
    gcs = list(gcs)
    pp, pg, rel = gc_membership(points, gcs)
    count = np.bincount(pp, minlength=len(points))
    limit = 1.0 / slack ** 2
    for g, gc in enumerate(gcs):
        if g in fixed:
            continue
        sel = pg == g
        p, r = pp[sel], rel[sel]
        d = gc.to_dict()
        key_t = np.array([k["t"] for k in d["keys"]])
        radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
        caps = np.array(d["caps"], dtype=np.float64)
        t = (np.clip(r[:, 0], -1.0, 1.0) + 1.0) / 2.0
        y = r[:, 1] * np.interp(t, key_t, radii[:, 0])
        z = r[:, 2] * np.interp(t, key_t, radii[:, 1])
        end = (r[:, 0] > 1.0).astype(int)
        past = np.clip(np.abs(r[:, 0]) - 1.0, 0.0, None) * caps[end]
        need = np.maximum(limit, _measure(key_t, radii, caps, t, y, z, past, end))
        free = count[p] > 1
        if owner is not None:
            free &= owner[p] != g
        for _ in range(2):
            for k in range(len(key_t)):
                for j in range(2):
                    trial = np.repeat(radii[None], len(SHRINK), 0)
                    trial[:, k, j] *= SHRINK
                    m = _measure(key_t, trial, caps, t, y, z, past, end)
                    ok = ((m <= need) | free).all(1)
                    radii[k, j] = trial[int(np.argmax(ok)), k, j]
        left = _measure(key_t, radii, caps, t, y, z, past, end) > 1.0
        np.subtract.at(count, p[left], 1)
        d["keys"] = [{**k, "radii": [float(v) for v in rr]} for k, rr in zip(d["keys"], radii)]
        gcs[g] = GeneralizedCylinder.from_dict(d)
    return gcs
