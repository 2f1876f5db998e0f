"""Brute-force check of the closest-point search: random Bezier GCs, points inside them, and the
nearest of many curve samples polished by Newton as the reference.

The fused kernel (`relative.py`) must return the global closest curve point; this module is the
independent reference it is held to, shared by tests/geometry and bench/geometry.py so the test
and the bench's `closest_point_excess_max` come from the same generator. Everything is
vectorised torch over points (Python loops run over GCs and chunks only).

Cases (`closest_point_cases`): Bezier curves of degree 1-5 from four families (gently to
sharply turning random walks; control points scattered in a box: loops and tight bends; flat
boxes turned in space, kept when two arcs pass close (CLOSE_ARCS): far apart along the curve,
or near enough along it for both to lie in the kernel's local window: tubes that overlap
themselves), radii up to the curvature limit 1 / max kappa, and points
  - uniform in the GC (tube and caps, in relative coordinates), a third of them on the tube's
    surface (at a tight bend: at the centre of curvature, where |C(t) - q| is flattest);
  - nearly equidistant from two arcs: the midpoint of two curve points more than two limits
    apart along the curve, moved until its two local foot points are equally far, then nudged by 1e-9 to 1e-3
    of the radius (which arc is closer is then a matter of that nudge).
"""
from __future__ import annotations

import math
from typing import Iterator, NamedTuple

import numpy as np
import torch

from .arclength import arc_lengths
from .arrays import dot
from .curves import BezierCurve
from .cylinder import GeneralizedCylinder
from .errors import GeometryError

# samples per block at each level of the reference's pruned search (16 sub-blocks a block)
LEVELS = (65536, 4096, 256, 16, 1)
REFERENCE_SAMPLES = 7 * LEVELS[0]  # 458,752 curve samples


def _polish(gc: GeneralizedCylinder, q: torch.Tensor, s: torch.Tensor, lo: torch.Tensor,
            hi: torch.Tensor, steps: int = 8) -> torch.Tensor:
    """Newton on |C(s) - q|^2 / 2 from s, kept in [lo, hi] (Gauss-Newton where f'' <= 0)."""
    for _ in range(steps):
        C, d1, d2 = gc.curve.evaluate(s)
        r = C - q
        g, gn = dot(r, d1), dot(d1, d1)
        H = gn + dot(r, d2)
        H = torch.where(H > 1e-3 * gn, H, gn)
        s = torch.minimum(torch.maximum(s - g / H, lo), hi)
    return s


def _segment_distance(p: torch.Tensor, A: torch.Tensor, E: torch.Tensor) -> torch.Tensor:
    """Distance from p (..., 3) to the segments [A, E] (..., 3) (broadcast)."""
    AE = E - A
    lam = (dot(p - A, AE) / dot(AE, AE).clamp(min=1e-300)).clamp(0.0, 1.0)
    e = A + lam[..., None] * AE - p
    return dot(e, e).sqrt()


def _capsules(curve, samples: int, levels) -> list:
    """Per level but the last, (A, E, dev): the first and last of each block of levels[l]
    consecutive samples C(i / (samples - 1)), and a bound dev on how far the block's samples
    stray from the segment [A, E]: the block lies in that capsule.

    Finest level: a sample P between A and E along the curve has |P - A| + |P - E| <= l, the
    arc length from A to E (chords are no longer than arcs), so it lies in the ellipsoid with
    foci A, E and major axis l, within sqrt(l^2 - |E - A|^2) / 2 of the segment (l by
    Gauss-Legendre, 1e-10 on top). Coarser levels: from their sub-blocks' capsules (the
    distance to a segment is convex, so a sub-capsule's farthest point is within dev_sub of
    an end of its own segment)."""
    size = levels[-2]
    first = torch.arange(0, samples, size, dtype=torch.float64)
    sa, sb = first / (samples - 1), (first + size - 1) / (samples - 1)
    A, E = curve.evaluate(sa)[0], curve.evaluate(sb)[0]
    arc = arc_lengths(curve, sa, sb, sub=2) * (1 + 1e-10)
    chord = (E - A).norm(dim=1)
    out = [(A, E, 0.5 * (arc * arc - chord * chord).clamp(min=0).sqrt() + 1e-15)]
    for size in reversed(levels[:-2]):
        sa, se, sdev = out[-1]
        k = size // levels[levels.index(size) + 1]
        sa, se, sdev = sa.reshape(-1, k, 3), se.reshape(-1, k, 3), sdev.reshape(-1, k)
        A, E = sa[:, 0], se[:, -1]
        far = torch.maximum(_segment_distance(sa, A[:, None], E[:, None]),
                            _segment_distance(se, A[:, None], E[:, None]))
        out.append((A, E, (far + sdev).max(1).values * (1 + 1e-12) + 1e-15))
    return out[::-1]


def nearest_sample(curve, q: torch.Tensor, samples: int = REFERENCE_SAMPLES, levels=LEVELS
                   ) -> torch.Tensor:
    """(N,) index i of the sample C(i / (samples - 1)) nearest each q (N, 3) (`candidates`)."""
    pi, idx, d = candidates(curve, q, samples, levels)
    best = torch.full((len(q),), math.inf, dtype=d.dtype).scatter_reduce(0, pi, d, "amin")
    win = d == best[pi]
    out = torch.empty(len(q), dtype=torch.int64)
    out[pi[win]] = idx[win]  # (ties: any of them)
    return out


def candidates(curve, q: torch.Tensor, samples: int = REFERENCE_SAMPLES, levels=LEVELS,
               chunk: int = 4096) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Blocks of levels[-2] samples that may hold the curve point nearest q (N, 3), as pairs:
    point index, the index i of the block's sample C(i / (samples - 1)) nearest that point,
    and its squared distance; samples divisible by levels[0], each level's blocks made of
    whole blocks of the next.

    A block is dropped only when its capsule (`_capsules`) is farther from q than a sample
    already seen, so every block with a sample nearer than the nearest sample, or a curve point
    nearer than that by more than its capsule's width, stays: the nearest sample among the
    pairs is the nearest of all (up to ties), and each arc that may hold the closest curve
    point has a pair."""
    caps = _capsules(curve, samples, levels)
    out = [_candidates(curve, caps, q[i:i + chunk], samples, levels)
           for i in range(0, len(q), chunk)]
    return (torch.cat([o[0] + i for o, i in zip(out, range(0, len(q), chunk))]),
            torch.cat([o[1] for o in out]), torch.cat([o[2] for o in out]))


def _candidates(curve, caps, q, samples, levels):
    pi = torch.arange(len(q)).repeat_interleave(samples // levels[0])
    bi = torch.arange(samples // levels[0]).repeat(len(q))
    for level, size in enumerate(levels[:-1]):
        A, E, dev = (x[bi] for x in caps[level])
        p = q[pi]
        lower = _segment_distance(p, A, E) - dev
        upper = torch.minimum(dot(A - p, A - p), dot(E - p, E - p)).sqrt()
        bound = torch.full((len(q),), math.inf, dtype=upper.dtype).scatter_reduce(
            0, pi, upper, "amin")
        keep = lower <= bound[pi]
        k = size // levels[level + 1]
        pi, bi = pi[keep], bi[keep]
        if level < len(levels) - 2:
            pi = pi.repeat_interleave(k)
            bi = (bi[:, None] * k + torch.arange(k)[None]).reshape(-1)
    k = levels[-2]
    idx = bi[:, None] * k + torch.arange(k)[None]  # (pairs, k) the blocks' samples
    e = curve.evaluate(idx.reshape(-1).double() / (samples - 1))[0].reshape(len(bi), k, 3)
    d, j = dot(e - q[pi][:, None], e - q[pi][:, None]).min(1)
    return pi, idx.gather(1, j[:, None])[:, 0], d


def reference_distance(gc: GeneralizedCylinder, q: np.ndarray, samples: int = REFERENCE_SAMPLES
                       ) -> np.ndarray:
    """(N,) distance from each q (N, 3) to the curve: from the nearest sample of each block that
    may hold the closest point (`candidates`: the nearest of `samples` curve points at uniform
    curve parameter among them), Newton within two sample spacings; the smallest distance
    found (all are distances to points on the curve)."""
    qt = torch.as_tensor(np.asarray(q, dtype=np.float64))
    pi, idx, d2 = candidates(gc.curve, qt, samples)
    h = 1.0 / (samples - 1)
    s0 = idx.double() * h
    s = _polish(gc, qt[pi], s0, (s0 - 2 * h).clamp(min=0.0), (s0 + 2 * h).clamp(max=1.0))
    d = torch.minimum(d2.sqrt(), (gc.curve.evaluate(s)[0] - qt[pi]).norm(dim=1))
    return torch.full((len(qt),), math.inf, dtype=d.dtype).scatter_reduce(0, pi, d, "amin").numpy()


def kernel_distance(gc: GeneralizedCylinder, q: np.ndarray) -> np.ndarray:
    """(N,) distance from each q (N, 3) to the foot point `gc.to_relative` found (past an end
    of the curve the foot is that end)."""
    rel = gc.to_relative(np.asarray(q, dtype=np.float64))
    foot = np.zeros_like(rel)
    foot[:, 0] = np.clip(rel[:, 0], -1.0, 1.0)
    return np.linalg.norm(gc.to_world(foot) - q, axis=1)


def closest_point_excess(gc: GeneralizedCylinder, q: np.ndarray) -> np.ndarray:
    """(N,) how much farther the kernel's foot point is than the reference's (<= 0: as near)."""
    return kernel_distance(gc, q) - reference_distance(gc, q)


# ---- random GCs and points ------------------------------------------------------------------
FAMILIES = ("walk", "box", "crossing", "neck")
# families whose curve must pass close to itself: two arcs, more than `sep` curvature limits but
# at most `span` of the length apart along the curve, closer than `gap` limits in space. A neck's
# arcs are near enough along the curve that both lie in the window the kernel's local search
# and its certificate of no nearer point cover (what a wrong certificate would miss)
CLOSE_ARCS = {"crossing": (4.0, 1.0, 1.5), "neck": (3.2, 0.35, 1.6)}


def _limit(gc: GeneralizedCylinder) -> float:
    """The curvature limit 1 / max kappa (inf for a straight curve)."""
    kmax = float(gc.curvature_samples().max())
    return 1.0 / kmax if kmax > 0 else math.inf


def _near_pairs(gc: GeneralizedCylinder, gap: float, sep: float, span: float = 1.0,
                n: int = 801):
    """Normalised arc lengths (t_i, t_j), t_i < t_j, of samples closer than `gap` in space,
    farther than `sep` but at most `span` L apart along the curve: two arcs that come close."""
    t = torch.linspace(0.0, 1.0, n, dtype=torch.float64)
    X = gc.curve.evaluate(gc.arc.s_of_t(t))[0]
    along = t[None, :] - t[:, None]
    ok = (torch.cdist(X, X) < gap) & (along * gc.length > sep) & (along <= span)
    i, j = ok.nonzero(as_tuple=True)
    return t[i], t[j]


def _may_pass_close(points: np.ndarray, sep: float, span: float, gap: float, n: int = 201
                    ) -> bool:
    """A cheap first look (n samples, chords for arc length) at CLOSE_ARCS' condition."""
    C, d1, d2 = BezierCurve(points).evaluate(torch.linspace(0.0, 1.0, n, dtype=torch.float64))
    limit = 1.0 / float((torch.linalg.cross(d1, d2).norm(dim=1) / d1.norm(dim=1) ** 3).max())
    arc = torch.cat([torch.zeros(1, dtype=C.dtype), (C[1:] - C[:-1]).norm(dim=1).cumsum(0)])
    along = (arc[None, :] - arc[:, None]).abs()
    return bool(((torch.cdist(C, C) < 1.1 * gap * limit) & (along > 0.9 * sep * limit)
                 & (along < 1.1 * span * float(arc[-1]))).any())


def _control_points(rng: np.random.Generator, degree: int, family: str) -> np.ndarray:
    n = degree + 1
    if family == "walk":  # gently to sharply turning random walk
        max_turn = rng.choice([np.pi / 5, np.pi / 2, 0.85 * np.pi])
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        pts = [rng.uniform(-0.3, 0.3, 3)]
        for _ in range(n - 1):
            r = rng.normal(size=3)
            r -= (r @ d) * d
            r /= np.linalg.norm(r)
            a = rng.uniform(0, max_turn)
            d = np.cos(a) * d + np.sin(a) * r
            pts.append(pts[-1] + rng.uniform(0.15, 0.5) * d)
        return np.array(pts)
    pts = rng.uniform(-0.5, 0.5, (n, 3))  # "box": loops, tight bends
    if family in CLOSE_ARCS:  # flat, then turned: the curve tends to pass close to itself
        pts[:, 2] *= 0.06
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        pts = pts @ q.T
    return pts


def random_bezier_gc(rng: np.random.Generator, degree: int, family: str | None = None
                     ) -> GeneralizedCylinder:
    """A Bezier GC of `degree` (family: one of FAMILIES, random by default) whose largest
    radius is at most the curvature limit 1 / max kappa (or 15% of the length for a straight
    curve), reached exactly in 40% of the GCs; twist, keys and caps random. A curve of a
    CLOSE_ARCS family passes close to itself and has radii of 0.8 to 1 limit: its tube overlaps
    itself there."""
    fam = family or str(rng.choice(FAMILIES if degree >= 3 else FAMILIES[:2] if degree == 2
                                   else FAMILIES[:1]))
    close = CLOSE_ARCS.get(fam)
    while True:
        pts = _control_points(rng, degree, fam)
        if close and not _may_pass_close(pts, *close):
            continue
        d = {"name": f"check_{fam}{degree}", "curve": {"type": "bezier", "points": pts.tolist()},
             "keys": [{"t": 0.0, "radii": [1.0, 1.0]}]}
        try:
            gc = GeneralizedCylinder.from_dict(d)
        except GeometryError:
            continue
        limit = min(_limit(gc), 0.15 * gc.length)
        if limit < 5e-3 * gc.length:  # a near-cusp: radii of a thread
            continue
        if close and len(_near_pairs(gc, close[2] * limit, close[0] * limit, close[1], 401)[0]
                         ) == 0:
            continue
        top = limit * (1 - 1e-6) * (1.0 if close or rng.random() < 0.4
                                    else rng.uniform(0.2, 1.0))
        nk = int(rng.integers(1, 4))
        ts = np.sort(rng.choice(np.linspace(0, 1, 11), nk, replace=False))
        radii = top * rng.uniform(0.8 if close else 0.4, 1.0, (nk, 2))
        radii[rng.integers(nk), rng.integers(2)] = top
        d["keys"] = [{"t": float(t), "radii": r.tolist(), "twist": float(rng.uniform(-180, 180))}
                     for t, r in zip(ts, radii)]
        d["caps"] = (top * rng.uniform(0.3, 1.5, 2)).tolist()
        return GeneralizedCylinder.from_dict(d)


def inside_points(rng: np.random.Generator, gc: GeneralizedCylinder, n: int) -> np.ndarray:
    """(n, 3) points inside the GC: uniform over its relative coordinates (tube and caps), a
    third of them on the tube's surface (a^2 + b^2 = 1)."""
    rel = np.stack([rng.uniform(-2, 2, 4 * n), rng.uniform(-1, 1, 4 * n),
                    rng.uniform(-1, 1, 4 * n)], 1)
    rel = rel[GeneralizedCylinder.inside_relative(rel)][:n]
    rim = rng.random(len(rel)) < 1 / 3
    tube = np.abs(rel[:, 0]) < 1
    ab = rel[rim & tube, 1:]
    rel[rim & tube, 1:] = ab / np.linalg.norm(ab, axis=1, keepdims=True).clip(1e-12)
    return gc.to_world(rel)


def equidistant_points(rng: np.random.Generator, gc: GeneralizedCylinder, n: int
                       ) -> np.ndarray:
    """(m <= n, 3) points within the smallest radius of two arcs of the curve and nearly
    equidistant from them (none where no two arcs, more than 2 curvature limits apart along
    the curve, come within twice the smallest radius)."""
    r_min = float(gc._key_r.min())
    limit = _limit(gc)
    ti, tj = _near_pairs(gc, 2 * r_min, 2 * min(limit, gc.length))
    if len(ti) == 0:
        return np.zeros((0, 3))
    pick = torch.as_tensor(rng.choice(len(ti), min(2 * n, len(ti)), replace=False))
    ti, tj = ti[pick], tj[pick]
    w = 2 * r_min / gc.length  # where each local foot point is sought, in normalised arc length
    s1, s2 = gc.arc.s_of_t(ti), gc.arc.s_of_t(tj)
    lo1, hi1 = gc.arc.s_of_t((ti - w).clamp(0, 1)), gc.arc.s_of_t((ti + w).clamp(0, 1))
    lo2, hi2 = gc.arc.s_of_t((tj - w).clamp(0, 1)), gc.arc.s_of_t((tj + w).clamp(0, 1))
    q = (gc.curve.evaluate(s1)[0] + gc.curve.evaluate(s2)[0]) / 2
    for _ in range(8):  # move q along the line between its two feet until they are equally far
        s1, s2 = _polish(gc, q, s1, lo1, hi1, 4), _polish(gc, q, s2, lo2, hi2, 4)
        F1, F2 = gc.curve.evaluate(s1)[0], gc.curve.evaluate(s2)[0]
        d1, d2 = (F1 - q).norm(dim=1), (F2 - q).norm(dim=1)
        u = (F1 - F2) / (F1 - F2).norm(dim=1, keepdim=True).clamp(min=1e-300)
        q = q + ((d1 - d2) / 2)[:, None] * u
    F1, F2 = gc.curve.evaluate(s1)[0], gc.curve.evaluate(s2)[0]
    d1, d2 = (F1 - q).norm(dim=1), (F2 - q).norm(dim=1)
    # both feet local minima strictly inside their windows, equally far, within the radius
    keep = ((s1 > lo1) & (s1 < hi1) & (s2 > lo2) & (s2 < hi2) & ((d1 - d2).abs() < 1e-10)
            & (d1 < r_min) & ((F1 - F2).norm(dim=1) > r_min))
    q = q[keep].numpy()[:n]
    nudge = rng.normal(size=q.shape)
    nudge *= (r_min * 10.0 ** rng.uniform(-9, -3, len(q)) / np.linalg.norm(nudge, axis=1))[:, None]
    return q + nudge


class Case(NamedTuple):
    """One random GC and points to check on it: `inside` (n, 3), `equidistant` (m, 3)."""

    gc: GeneralizedCylinder
    family: str
    at_limit: bool  # its largest radius is the curvature limit
    inside: np.ndarray
    equidistant: np.ndarray

    @property
    def points(self) -> np.ndarray:
        return np.concatenate([self.inside, self.equidistant])


def closest_point_cases(seed: int = 0, n_gcs: int = 40, points_per_gc: int = 2500
                        ) -> Iterator[Case]:
    """n_gcs random Bezier GCs of degrees 1-5 in turn, each degree's families in turn
    (`random_bezier_gc`), each with
    `points_per_gc` points inside and up to a quarter as many nearly equidistant from two arcs
    (`equidistant_points`)."""
    rng = np.random.default_rng(seed)
    for g in range(n_gcs):
        degree = g % 5 + 1
        allowed = FAMILIES if degree >= 3 else FAMILIES[:2] if degree == 2 else FAMILIES[:1]
        gc = random_bezier_gc(rng, degree, allowed[(g // 5) % len(allowed)])
        family = gc.name.removeprefix("check_")[:-1]
        limit = min(_limit(gc), 0.15 * gc.length)
        yield Case(gc, family, bool(float(gc._key_r.max()) >= limit * (1 - 1e-5)),
                   inside_points(rng, gc, points_per_gc),
                   equidistant_points(rng, gc, points_per_gc // 4))


def closest_point_check(seed: int = 0, n_gcs: int = 40, points_per_gc: int = 2500) -> dict:
    """The kernel's foot points against the reference on `closest_point_cases`: the largest
    excess of the kernel's distance over the reference's (<= 1e-9: exact), the smallest (the
    kernel's foot lies on the curve, so below -1e-9 would mean the reference missed the closest
    point) and what was checked. The property test and bench/geometry.py both report this."""
    worst, worst_case, points, equidistant, at_limit = -math.inf, "", 0, 0, 0
    least = math.inf
    families: dict[str, int] = {}
    for case in closest_point_cases(seed, n_gcs, points_per_gc):
        excess = closest_point_excess(case.gc, case.points)
        least = min(least, float(excess.min()))
        if excess.max() > worst:
            worst = float(excess.max())
            worst_case = (f"{case.gc.name}: {int((excess > 1e-9).sum())} of {len(excess)} points "
                          f"farther by more than 1e-9")
        points += len(excess)
        equidistant += len(case.equidistant)
        at_limit += case.at_limit
        families[case.family] = families.get(case.family, 0) + 1
    return {"closest_point_excess_max": worst, "closest_point_excess_min": least,
            "closest_point_points": points,
            "closest_point_equidistant_points": equidistant, "closest_point_gcs": n_gcs,
            "closest_point_gcs_at_curvature_limit": at_limit,
            "closest_point_gc_families": families, "closest_point_worst_gc": worst_case}
