"""Sample generators for data preparation: surface points, GC membership, volume points.

All functions are vectorised over points; the only Python loops run over GCs or over
rejection rounds. Points are float64 (N, 3) in the normalised frame.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ngc_gen.data.errors import DataError
from ngc_gen.geometry import GeneralizedCylinder

Pairs = tuple[np.ndarray, np.ndarray, np.ndarray]  # point index (P,), gc index (P,), rel (P, 3)


def sample_surface(vertices: np.ndarray, faces: np.ndarray, n: int, rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray]:
    """n points uniform over the surface area, with their unit face normals.

    vertices (V, 3), faces (F, 3) -> points (n, 3) float64, normals (n, 3) float64.
    Faces are drawn by area, positions by uniform barycentric coordinates (sqrt trick).
    """
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]  # (F, 3, 3)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    total = area2.sum()
    if not total > 0:
        raise DataError("every face of the mesh has zero area", field="mesh",
                        fix="give a mesh with non-degenerate triangles")
    face = rng.choice(len(tri), size=n, p=area2 / total)
    r1, r2 = rng.random((2, n))
    s = np.sqrt(r1)
    w = np.stack([1.0 - s, s * (1.0 - r2), s * r2], axis=1)  # (n, 3) barycentric
    points = np.einsum("nk,nkd->nd", w, tri[face])
    normals = cross[face] / area2[face, None]
    return points, normals


def gc_membership(points: np.ndarray, gcs: Sequence[GeneralizedCylinder],
                  skip: np.ndarray | None = None, margin: float = 0.0) -> Pairs:
    """Every (point, GC) pair with the point inside the GC, and its relative coordinates.

    points (N, 3) -> pair_point (P,) int64, pair_gc (P,) int64, pair_rel (P, 3) float64 [u, a, b],
    sorted by point then GC. Only points inside a GC's bounding box are sent to ``to_relative``.
    skip (N,) int, optional: GC index per point whose pair the caller already has (left out).
    margin: a point pairs with a GC up to relative radius 1 + margin (0: inside it), so a GC's
    network can be trained a little past its boundary (prepare.pair_margin).
    """
    pp, pg, pr = [], [], []
    limit = (1.0 + float(margin)) ** 2
    for g, gc in enumerate(gcs):
        lo, hi = gc.bounds()
        if margin > 0:   # rho <= 1 + m lies within m x the GC's largest extent of its box
            grow = float(margin) * float((hi - lo).max())
            lo, hi = lo - grow, hi + grow
        mask = ((points >= lo) & (points <= hi)).all(axis=1)
        if skip is not None:
            mask &= skip != g
        cand = np.flatnonzero(mask)
        if len(cand) == 0:
            continue
        rel = np.asarray(gc.to_relative(points[cand]))
        inside = np.asarray(GeneralizedCylinder.relative_measure(rel)) <= limit
        pp.append(cand[inside])
        pg.append(np.full(int(inside.sum()), g, dtype=np.int64))
        pr.append(rel[inside])
    return _sorted_pairs(pp, pg, pr)


def _sorted_pairs(pp: list, pg: list, pr: list) -> Pairs:
    """Concatenate pair pieces and sort them by point, then GC."""
    if not pp:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
    pp, pg, pr = np.concatenate(pp), np.concatenate(pg), np.concatenate(pr)
    order = np.lexsort((pg, pp))
    return pp[order], pg[order], pr[order]


def sample_volume(gcs: Sequence[GeneralizedCylinder], n: int, rng: np.random.Generator,
                  max_rounds: int = 100, shell: float = 0.0,
                  overlap: bool = False) -> tuple[np.ndarray, Pairs]:
    """n points uniform inside the union of the GCs, with their GC membership pairs.

    Candidates come from the mixture of GC bounding boxes (box chosen by volume), are kept if
    inside the GC of their box, then thinned with probability 1/k for a point inside k GCs:
    the kept density is then constant over the union, so overlaps are not over-sampled.
    The first round draws n candidates, later ones scale by the measured acceptance, so few
    candidates are wasted. Returns points (n, 3) and pairs as in ``gc_membership``.
    shell > 0: only points in the outer shell of their GC, relative radius in [1 - shell, 1]
    (where the blended union fades the GC out, and where a GC holding a point alone must still
    be right far from the surface).
    overlap: only points inside two or more GCs (where their networks must agree), uniform
    over the overlaps.
    """
    if n <= 0:
        return np.zeros((0, 3)), (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    bounds = np.array([np.stack(gc.bounds()) for gc in gcs])  # (G, 2, 3)
    lo, ext = bounds[:, 0], bounds[:, 1] - bounds[:, 0]
    box_vol = ext.prod(axis=1)
    probs = box_vol / box_vol.sum()
    pts, pairs = [], []
    have, drawn, rate = 0, 0, 1.0
    for _ in range(max_rounds):
        if have >= n:
            break
        m = int(min(max(1.1 * (n - have) / rate, 1024), 4_000_000))
        which = rng.choice(len(gcs), size=m, p=probs)
        cand = lo[which] + rng.random((m, 3)) * ext[which]
        own = np.zeros(m, dtype=bool)
        own_rel = np.zeros((m, 3))
        for g, gc in enumerate(gcs):
            idx = np.flatnonzero(which == g)
            if len(idx):
                own_rel[idx] = np.asarray(gc.to_relative(cand[idx]))
                own[idx] = np.asarray(GeneralizedCylinder.inside_relative(own_rel[idx]))
        if shell > 0:
            depth = np.sqrt(np.asarray(GeneralizedCylinder.relative_measure(own_rel)))
            own &= depth >= 1.0 - shell
        cand, which, own_rel = cand[own], which[own], own_rel[own]
        pp, pg, pr = gc_membership(cand, gcs, skip=which)  # the other GCs holding each candidate
        pp, pg, pr = _sorted_pairs([pp, np.arange(len(cand))], [pg, which], [pr, own_rel])
        k = np.bincount(pp, minlength=len(cand))  # >= 1: every candidate is in its own GC
        keep = rng.random(len(cand)) * k < 1.0
        if overlap:
            keep &= k >= 2
        new_index = np.cumsum(keep) - 1 + have
        sel = keep[pp]
        pts.append(cand[keep])
        pairs.append((new_index[pp[sel]], pg[sel], pr[sel]))
        have += int(keep.sum())
        drawn += m
        rate = max(have / drawn, 1e-4)
    if have < n:
        raise DataError(f"could only place {have} of {n} volume samples inside the GCs "
                        f"(acceptance {rate:.2g})", field="gcs",
                        fix="check that the GCs have volume (radii and length not near zero)")
    points = np.concatenate(pts)[:n]
    pp, pg, pr = (np.concatenate(x) for x in zip(*pairs))
    sel = pp < n
    return points, (pp[sel], pg[sel], pr[sel])
