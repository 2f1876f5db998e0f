"""What the relative-coordinate kernel (`relative.py`) reads about one GC, and how its coarse
tables are built: the coarse polyline's vertices, their cover and reach balls, the convexity
radii of the seed's descent, the segments' bulge and the certificate's curvature bounds (the
module docstring of `relative.py` says how each is used)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

# the closest-point certificate holds over the segments of the nearest coarse vertex and SPAN
# coarse vertices each side: wide enough that the coarse balls a point may be nearer to than
# its foot point lie within it, for most points
SPAN = 2


class RelativeTables(NamedTuple):
    """Everything the kernel reads about one GC (float64 / int64 numpy arrays).

    breaks (P+1,), coef (P, D+1, 3): the curve as P polynomial pieces on its own parameter s,
      coef[i, k] the power-basis coefficient of (s - breaks[i])^k.
    poly_x (K+1, 3), poly_s (K+1,), poly_d (K+1, 3): dense polyline vertices C(s_k), their
      parameters and the derivatives C'(s_k).
    coarse (Kc+1,) int64: indices of the coarse vertices (0, stride, 2 stride, ..., K).
    cover (Kc+1,): radius of the ball around each coarse vertex; the balls enclose the GC.
    convex (Kc+1,): within this distance of a coarse vertex, |C(s) - q|^2 is convex over the
      arc between its coarse neighbours (0 where no such distance exists).
    chord (K,), bulge (K,): |x_{j+1} - x_j| and how far segment j's arc strays from that chord
      (`segment_bulge`).
    owned (Kc+2,) int64: coarse vertex c owns segments owned[c] <= j < owned[c+1].
    reach (Kc+1,): radius of a ball around coarse vertex c holding the arc of its segments.
    span_k, span_dk (Kc+1,): bounds on |C_tt| and |C_ttt| (arc length) over the segments of
      coarse vertices c - SPAN to c + SPAN (`span_bounds`).
    arc_t (M+1,): normalised arc length at s = linspace(0, 1, M+1).
    rep_arc, rep_t: the reparameterisation (arc length -> network t) or empty arrays.
    frame_r (Q+1, 3): RMF reference vectors at s = linspace(0, 1, Q+1).
    key_t (nk,), key_r (nk, 2), key_w (nk,) radians; twisted: any key twist != 0; caps (2,).
    length: the curve's arc length (the polyline's vertices lie at arc length k L / K).
    """

    breaks: np.ndarray
    coef: np.ndarray
    poly_x: np.ndarray
    poly_s: np.ndarray
    poly_d: np.ndarray
    coarse: np.ndarray
    cover: np.ndarray
    convex: np.ndarray
    chord: np.ndarray
    bulge: np.ndarray
    owned: np.ndarray
    reach: np.ndarray
    span_k: np.ndarray
    span_dk: np.ndarray
    arc_t: np.ndarray
    rep_arc: np.ndarray
    rep_t: np.ndarray
    frame_r: np.ndarray
    key_t: np.ndarray
    key_r: np.ndarray
    key_w: np.ndarray
    twisted: bool
    caps: np.ndarray
    length: float


def coarse_indices(n_vertices: int, stride: int) -> np.ndarray:
    """0, stride, 2 stride, ... and always the last vertex index n_vertices - 1."""
    c = np.arange(0, n_vertices, stride)
    return c if c[-1] == n_vertices - 1 else np.append(c, n_vertices - 1)


def coarse_cover(poly_x: np.ndarray, fine_radius: np.ndarray, coarse: np.ndarray) -> np.ndarray:
    """Radius of a ball around each coarse vertex holding the fine balls (poly_x[k], r_k) of the
    dense vertices nearest to it in index (those up to halfway to its coarse neighbours)."""
    k = np.arange(len(poly_x))
    owner = np.abs(k[:, None] - coarse[None, :]).argmin(1)
    reach = np.linalg.norm(poly_x - poly_x[coarse[owner]], axis=1) + fine_radius
    out = np.zeros(len(coarse))
    np.maximum.at(out, owner, reach)
    return out


def coarse_convex(kappa: np.ndarray, coarse: np.ndarray, segments: int, length: float
                  ) -> np.ndarray:
    """Distance rho_c from coarse vertex c within which f(t) = |C(t) - q|^2 / 2 is convex in arc
    length t over the window between c's coarse neighbours.

    There f'' = 1 - kappa (q - C).N >= 1 - kappa |q - C(t)| and |q - C(t)| <= |q - C(t_c)| + l_c,
    l_c the arc length from c to the farther window end: f'' > 0 if |q - C(t_c)| < 1 / kappa_max
    - l_c. kappa: curvature at n uniform arc-length samples per polyline segment (K n + 1 of
    them); its window maximum is bounded by the largest sample plus the largest change between
    neighbouring samples (kappa is smooth: the excess between samples is second order)."""
    n = (len(kappa) - 1) // segments
    slack = np.abs(np.diff(kappa)).max() if len(kappa) > 1 else 0.0
    lo = coarse[np.maximum(np.arange(len(coarse)) - 1, 0)]
    hi = coarse[np.minimum(np.arange(len(coarse)) + 1, len(coarse) - 1)]
    kmax = np.array([kappa[a * n:b * n + 1].max() for a, b in zip(lo, hi)])
    kmax = (kmax + slack) * (1 + 1e-6)
    ell = length * np.maximum(coarse - lo, hi - coarse) / segments
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = 1.0 / kmax - ell * (1 + 1e-6)
    return np.where(rho > 0, rho, 0.0)  # NaN (a cusp): 0, never convex


def segment_bulge(poly_x: np.ndarray, arc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Chord lengths c_j = |x_{j+1} - x_j| (K,) and bulges b_j = sqrt(l_j^2 - c_j^2) / 2 of the
    polyline's segments, l_j (K,) the arc length of segment j.

    A point P on the arc of segment j has |P - x_j| + |P - x_{j+1}| <= l_j (chords are no
    longer than arcs): it lies in the ellipsoid with foci x_j, x_{j+1} and major axis l_j, and
    that ellipsoid lies within b_j (its semi-minor axis) of the chord. So the arc is no nearer
    to q than |q - chord| - b_j: no curvature bound needed, and b_j ~ 0.14 kappa l_j^2."""
    c = np.linalg.norm(np.diff(poly_x, axis=0), axis=1)
    ell = np.maximum(arc * (1 + 1e-9), c)
    return c, 0.5 * np.sqrt(ell * ell - c * c) + 1e-15


def coarse_owned(coarse: np.ndarray) -> np.ndarray:
    """(Kc+2,) segment bounds: coarse vertex c owns the segments j with owned[c] <= j <
    owned[c+1], those nearer to it in index than to its coarse neighbours."""
    mid = (coarse[:-1] + coarse[1:] + 1) // 2
    return np.concatenate([[0], mid, [coarse[-1]]]).astype(np.int64)


def coarse_reach(poly_x: np.ndarray, bulge: np.ndarray, coarse: np.ndarray, owned: np.ndarray
                 ) -> np.ndarray:
    """(Kc+1,) radius of a ball around coarse vertex c holding the arcs of its segments: each
    arc lies within b_j of its chord (`segment_bulge`), so within the farther chord end plus b_j
    of any centre."""
    out = np.zeros(len(coarse))
    for c in range(len(coarse)):
        j = np.arange(owned[c], owned[c + 1])
        ends = np.maximum(np.linalg.norm(poly_x[j] - poly_x[coarse[c]], axis=1),
                          np.linalg.norm(poly_x[j + 1] - poly_x[coarse[c]], axis=1))
        out[c] = (ends + bulge[j]).max() if len(j) else 0.0
    return out * (1 + 1e-12) + 1e-15


def span_bounds(ctt: np.ndarray, owned: np.ndarray, segments: int, length: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(Kc+1,) bounds on |C_tt| (the curvature) and |C_ttt| in arc length t over the segments
    of coarse vertices c - SPAN to c + SPAN, from ctt (K n + 1, 3): C_tt at n uniform arc-length
    samples per segment. A window's largest sample (or difference quotient, for C_ttt) plus the
    largest change between neighbouring ones (C is smooth: the excess between samples is of
    that order), 5% on top."""
    n = (len(ctt) - 1) // segments
    kappa = np.linalg.norm(ctt, axis=1)
    dq = np.linalg.norm(np.diff(ctt, axis=0), axis=1) * (segments * n / length)
    slack_k = np.abs(np.diff(kappa)).max()
    slack_dk = np.abs(np.diff(dq)).max() if len(dq) > 1 else 0.0
    Kc = len(owned) - 2
    lo = owned[np.maximum(np.arange(Kc + 1) - SPAN, 0)] * n
    hi = owned[np.minimum(np.arange(Kc + 1) + SPAN + 1, Kc + 1)] * n
    k = np.array([kappa[a:b + 1].max() for a, b in zip(lo, hi)])
    dk = np.array([dq[a:b].max() for a, b in zip(lo, hi)])
    return (k + slack_k) * 1.05 + 1e-12, (dk + slack_dk) * 1.05  # (no 0 to divide by)
