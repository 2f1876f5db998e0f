"""GCs shrunk to the least volume that still holds their samples (docs/transfer.md).

Growth point by point (``hug.hug_to_cover``) overshoots: each key and cap takes the largest
factor any of its points asks for. ``tighten`` then fits each GC's key radii and caps jointly
(``least_volume``): least volume subject to every sample it holds staying inside. A sample's
measure (y / r_y(t))^2 + (z / r_z(t))^2 + (past / cap)^2 is convex in the radii (r(t) lerps
two keys), so SLSQP over their logarithms finds the fit a key at a time cannot: one key grows
a little where that lets its neighbours shrink much more.

With `release`, a sample that another GC also holds may leave; without it (the transfer's
way) a GC only shrinks into empty space: releasing takes surface from parts (measured on the
turned 0 A.D. animals: the union's outside volume 7% lower, purity against the rigs 2.7
points lower), since which GC a sample belongs to is known only roughly.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from ngc_gen.data.mesh.sampling import gc_membership
from ngc_gen.geometry import GeneralizedCylinder


def _lerp_weights(key_t: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(P, K) weights of each key in the radii lerped at t (P,) (clamped at the ends)."""
    K = len(key_t)
    W = np.zeros((len(t), K))
    if K == 1:
        W[:, 0] = 1.0
        return W
    hi = np.clip(np.searchsorted(key_t, t, side="right"), 1, K - 1)
    lo = hi - 1
    w = np.clip((t - key_t[lo]) / (key_t[hi] - key_t[lo]), 0.0, 1.0)
    rows = np.arange(len(t))
    W[rows, lo] = 1.0 - w
    W[rows, hi] += w
    return W


def _volume_grad(key_t: np.ndarray, length: float, a: np.ndarray, b: np.ndarray,
                 c: np.ndarray) -> tuple[float, np.ndarray]:
    """Volume of a GC of arc `length` with key radii a, b (K,) lerped along it and caps c (2,)
    (half-ellipsoids), and its gradient with respect to (a, b, c) (2K + 2,)."""
    h = np.diff(key_t) * length
    tube = float(np.sum(h * (a[:-1] * b[:-1] / 3 + a[1:] * b[1:] / 3
                             + (a[:-1] * b[1:] + a[1:] * b[:-1]) / 6)))
    ga, gb = np.zeros_like(a), np.zeros_like(b)
    ga[:-1] += h * (b[:-1] / 3 + b[1:] / 6)
    ga[1:] += h * (b[1:] / 3 + b[:-1] / 6)
    gb[:-1] += h * (a[:-1] / 3 + a[1:] / 6)
    gb[1:] += h * (a[1:] / 3 + a[:-1] / 6)
    cap = 2.0 / 3.0 * (a[0] * b[0] * c[0] + a[-1] * b[-1] * c[1])
    ga[[0, -1]] += 2.0 / 3.0 * np.array([b[0] * c[0], b[-1] * c[1]])
    gb[[0, -1]] += 2.0 / 3.0 * np.array([a[0] * c[0], a[-1] * c[1]])
    gc = 2.0 / 3.0 * np.array([a[0] * b[0], a[-1] * b[-1]])
    return np.pi * (tube + cap), np.pi * np.r_[ga, gb, gc]


def gc_volume(gc: GeneralizedCylinder) -> float:
    """A GC's volume: elliptic sections lerped between its keys along the arc, two caps."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    if len(key_t) == 1:
        key_t, radii = np.array([0.0, 1.0]), np.repeat(radii, 2, 0)
    return _volume_grad(key_t, gc.length, radii[:, 0], radii[:, 1], np.asarray(d["caps"]))[0]


#: the constraint set SLSQP starts from: per arc bin (of T_BINS, tube and each cap apart) the
#: FIRST_PER_BIN samples nearest their limit at the start, and the FIRST_LOWEST nearest overall
T_BINS, FIRST_PER_BIN, FIRST_LOWEST = 64, 8, 256


def _first_set(t: np.ndarray, E: np.ndarray, slack0: np.ndarray) -> np.ndarray:
    """Indices of the samples the fit starts with (T_BINS...): at most a few hundred of the
    tens of thousands, spread along the GC so that the shrunk radii rarely leave one out."""
    b = np.minimum((t * T_BINS).astype(int), T_BINS - 1) * 3 + (E @ np.array([1, 2])).astype(int)
    order = np.lexsort((slack0, b))
    rank = np.arange(len(order)) - np.searchsorted(b[order], b[order], side="left")
    return np.union1d(order[rank < FIRST_PER_BIN], np.argsort(slack0)[:FIRST_LOWEST])


def least_volume(key_t: np.ndarray, radii: np.ndarray, caps: np.ndarray, length: float,
                 samples: tuple, need: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Key radii (K, 2) and caps (2,) of least volume with each sample's measure within its
    `need` (P,); samples = (t, y, z, past, end) (P,) each: arc t, offsets in the frame,
    distance past end `end` (0 / 1; 0 in the tube). SLSQP over the logarithms from the given
    radii and caps, then scaled up uniformly by any excess left (so exact).

    Active set: at the optimum only a handful of samples touch the surface, and SLSQP's cost
    grows with its constraints (32k samples: about a second). The fit runs on a few hundred
    (``_first_set``); a sample that the result leaves outside joins them and the fit reruns from
    the start, until none does: the same optimum as with every sample (on the turned 0 A.D.
    animals' GCs: radii equal to 1e-12 but where the least volume is flat, 3x faster)."""
    t, y, z, past, end = samples
    K = len(key_t)
    if K < 2 or not len(t):
        return radii, caps
    W = _lerp_weights(key_t, t)
    E = np.stack([(end == 0) & (past > 0), (end == 1) & (past > 0)], 1).astype(float)
    x0 = np.log(np.r_[radii[:, 0], radii[:, 1], caps])
    v0 = _volume_grad(key_t, length, radii[:, 0], radii[:, 1], caps)[0]

    def parts(x, s):
        e = np.exp(x)
        a, b, c = e[:K], e[K:2 * K], e[2 * K:]
        return a, b, c, W[s] @ a, W[s] @ b, E[s] @ c + (1.0 - E[s].sum(1))

    def objective(x):
        a, b, c = np.exp(x[:K]), np.exp(x[K:2 * K]), np.exp(x[2 * K:])
        v, g = _volume_grad(key_t, length, a, b, c)
        return v / v0, g * np.exp(x) / v0

    def slack(x, s=slice(None)):
        _, _, _, ra, rb, rc = parts(x, s)
        return 1.0 - ((y[s] / ra) ** 2 + (z[s] / rb) ** 2 + (past[s] / rc) ** 2) / need[s]

    def jac(x, s):
        a, b, c, ra, rb, rc = parts(x, s)
        n = need[s]
        return np.hstack([(2.0 * y[s] ** 2 / ra ** 3 / n)[:, None] * W[s] * a,
                          (2.0 * z[s] ** 2 / rb ** 3 / n)[:, None] * W[s] * b,
                          (2.0 * past[s] ** 2 / rc ** 3 / n)[:, None] * E[s] * c])

    sel = _first_set(t, E, slack(x0))
    while True:
        res = minimize(objective, x0, jac=True, method="SLSQP", options={"maxiter": 100},
                       constraints=[{"type": "ineq", "fun": slack, "args": (sel,),
                                     "jac": jac}])
        x = res.x if np.all(np.isfinite(res.x)) else x0
        out = np.setdiff1d(np.flatnonzero(slack(x) < -1e-6), sel)
        if not len(out):
            break
        sel = np.union1d(sel, out)
    x = x + 0.5 * float(np.log(max(1.0 - float(slack(x).min()), 1.0)))
    radii = np.exp(np.stack([x[:K], x[K:2 * K]], 1))
    return radii, np.maximum(np.exp(x[2 * K:]), min_caps(radii))


#: a cap is at least this share of the smaller radius at its end: a longer cap only loosens
#: each sample's measure, and a cap shrunk toward 0 (5e-207 seen) is a degenerate GC whose log
#: cap a generator cannot learn (its samples decoded caps of 0, which no annotation accepts)
MIN_CAP = 0.1


def min_caps(radii: np.ndarray) -> np.ndarray:
    """The least caps (2,) of a GC with key radii (K, 2): MIN_CAP x the smaller end radius."""
    return MIN_CAP * np.array([radii[0].min(), radii[-1].min()])


def _samples(gc: GeneralizedCylinder, rel: np.ndarray) -> tuple:
    """(t, y, z, past, end) of points at relative coordinates rel (P, 3) in gc (least_volume)."""
    d = gc.to_dict()
    key_t = np.array([k["t"] for k in d["keys"]])
    radii = np.array([k["radii"] for k in d["keys"]], dtype=np.float64)
    caps = np.asarray(d["caps"], dtype=np.float64)
    t = (np.clip(rel[:, 0], -1.0, 1.0) + 1.0) / 2.0
    end = (rel[:, 0] > 1.0).astype(int)
    return (t, rel[:, 1] * np.interp(t, key_t, radii[:, 0]),
            rel[:, 2] * np.interp(t, key_t, radii[:, 1]),
            np.clip(np.abs(rel[:, 0]) - 1.0, 0.0, None) * caps[end], end)


def tighten(gcs: list[GeneralizedCylinder], points: np.ndarray, owner: np.ndarray | None = None,
            slack: float = 1.02, fixed: set[int] = frozenset(),
            release: bool = False) -> list[GeneralizedCylinder]:
    """Each GC (but those `fixed`) refitted to its least volume (``least_volume``) with every
    sample (N, 3) it holds staying inside with `slack` (or as deep as it is already);
    `release`: except samples another GC also holds and that are not its own (owner (N,):
    the GC each sample belongs to, -1: none), one GC after another (module docstring)."""
    gcs = list(gcs)
    pp, pg, rel = gc_membership(points, gcs)
    count = np.bincount(pp, minlength=len(points))
    for g, gc in enumerate(gcs):
        if g in fixed:
            continue
        sel = pg == g
        p = pp[sel]
        keep = ~((count[p] > 1) & release)
        if owner is not None:
            keep |= owner[p] == g
        need = np.maximum(1.0 / slack ** 2, GeneralizedCylinder.relative_measure(rel[sel]))
        d = gc.to_dict()
        key_t = np.array([k["t"] for k in d["keys"]])
        radii, caps = least_volume(key_t, np.array([k["radii"] for k in d["keys"]], np.float64),
                                   np.asarray(d["caps"], np.float64), gc.length,
                                   tuple(v[keep] for v in _samples(gc, rel[sel])), need[keep])
        d["keys"] = [{**k, "radii": [float(v) for v in rr]} for k, rr in zip(d["keys"], radii)]
        d["caps"] = [float(c) for c in caps]
        gcs[g] = GeneralizedCylinder.from_dict(d)
        if release:
            left = ~np.asarray(gcs[g].contains(points[p]), bool)
            np.subtract.at(count, p[left], 1)
    return gcs
