"""Relative coordinates of many points in one fused pass (numba, all CPU cores).

Per point, in float64 whatever the input dtype (DESIGN.md section 2):
1. seed: the nearest vertex of a coarse polyline (every `stride`-th vertex of the dense one),
   then the nearest dense vertex between that vertex's two coarse neighbours, then the closest
   point on the two dense segments around it: about 2 sqrt(K) candidates instead of K;
2. cull (optional): a point outside every coarse cover ball is outside the GC, so it skips the
   rest (`RelativeTables.cover_radius` says why the balls enclose the GC);
3. Newton on f(s) = |C(s) - q|^2 / 2 from the seed, kept within two dense segments each side,
   until a step moves s by at most NEWTON_TOL: the seed is O(h^2) close, so two steps reach
   rounding. Where f'' <= 0 (q past the centre of curvature) it takes a Gauss-Newton step;
4. frame, twist, radii and caps at the foot point as `GeneralizedCylinder` defines them.

A torch implementation of the same steps would run ~60 small kernels per chunk of points, each
a pass over memory; fused, a point costs ~100 ns on one core. Results match the float64
definition to rounding (round trip ~1e-15 on points inside, float64).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
import torch
from numba import njit, prange

NEWTON_MAX_STEPS = 8
# stop once a step moves s by at most this: Newton converges quadratically from the O(h^2) seed,
# so after a step of 1e-7 s is within ~C 1e-14 of the root (C = |f'''| / 2|f''|, O(1)): two
# steps for most points. Waiting for an exactly zero step instead ended in rounding ping-pong
# for a third of the points (8 steps)
NEWTON_TOL = 1e-7
# the kernels may fuse a * b + c into one rounding (FMA): a few percent; per point the same
# compiled code runs whatever the batch, so results stay reproducible
FASTMATH = {"contract"}


class RelativeTables(NamedTuple):
    """Everything the kernel reads about one GC (float64 / int64 numpy arrays).

    breaks (P+1,), coef (P, D+1, 3): the curve as P polynomial pieces on its own parameter s,
      coef[i, k] the power-basis coefficient of (s - breaks[i])^k.
    poly_x (K+1, 3), poly_s (K+1,): dense polyline vertices C(s_k) and their parameters.
    coarse (Kc+1,) int64: indices of the coarse vertices (0, stride, 2 stride, ..., K).
    cover (Kc+1,): radius of the ball around each coarse vertex; the balls enclose the GC.
    arc_t (M+1,): normalised arc length at s = linspace(0, 1, M+1).
    rep_arc, rep_t: the reparameterisation (arc length -> network t) or empty arrays.
    frame_r (Q+1, 3): RMF reference vectors at s = linspace(0, 1, Q+1).
    key_t (nk,), key_r (nk, 2), key_w (nk,) radians; twisted: any key twist != 0; caps (2,).
    """

    breaks: np.ndarray
    coef: np.ndarray
    poly_x: np.ndarray
    poly_s: np.ndarray
    coarse: np.ndarray
    cover: np.ndarray
    arc_t: np.ndarray
    rep_arc: np.ndarray
    rep_t: np.ndarray
    frame_r: np.ndarray
    key_t: np.ndarray
    key_r: np.ndarray
    key_w: np.ndarray
    twisted: bool
    caps: np.ndarray


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


@njit(cache=True, fastmath=FASTMATH)
def _piece(s, breaks):
    """Index of the polynomial piece holding s (clamped)."""
    P = breaks.shape[0] - 1
    if P == 1:
        return 0
    lo, hi = 0, P
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if breaks[mid] <= s:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True, fastmath=FASTMATH)
def _curve(s, breaks, coef):
    """C(s), C'(s), C''(s) by Horner's rule on the piece holding s; 9 floats."""
    i = _piece(s, breaks)
    h = s - breaks[i]
    D = coef.shape[1] - 1
    cx = coef[i, D, 0]
    cy = coef[i, D, 1]
    cz = coef[i, D, 2]
    dx = dy = dz = 0.0
    ex = ey = ez = 0.0
    for k in range(D - 1, -1, -1):
        ex = ex * h + 2.0 * dx
        ey = ey * h + 2.0 * dy
        ez = ez * h + 2.0 * dz
        dx = dx * h + cx
        dy = dy * h + cy
        dz = dz * h + cz
        cx = cx * h + coef[i, k, 0]
        cy = cy * h + coef[i, k, 1]
        cz = cz * h + coef[i, k, 2]
    return cx, cy, cz, dx, dy, dz, ex, ey, ez


@njit(cache=True, fastmath=FASTMATH)
def _interp(x, xp, fp):
    """np.interp (clamped) for increasing xp."""
    n = xp.shape[0]
    if x <= xp[0]:
        return fp[0]
    if x >= xp[n - 1]:
        return fp[n - 1]
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    w = (x - xp[lo]) / (xp[hi] - xp[lo])
    return fp[lo] * (1.0 - w) + fp[hi] * w


@njit(cache=True, fastmath=FASTMATH)
def _uniform_cell(x, M):
    """Cell index and weight of x in linspace(0, 1, M + 1), clamped."""
    xs = min(max(x, 0.0), 1.0) * M
    i = min(int(xs), M - 1)
    return i, xs - i


@njit(cache=True, fastmath=FASTMATH)
def _dist2(qx, qy, qz, x, k):
    ax = qx - x[k, 0]
    ay = qy - x[k, 1]
    az = qz - x[k, 2]
    return ax * ax + ay * ay + az * az


@njit(cache=True, fastmath=FASTMATH)
def _segment(qx, qy, qz, x, ps, a):
    """Closest point of segment (x[a], x[a+1]) to q: (parameter s, squared distance)."""
    abx = x[a + 1, 0] - x[a, 0]
    aby = x[a + 1, 1] - x[a, 1]
    abz = x[a + 1, 2] - x[a, 2]
    lam = ((qx - x[a, 0]) * abx + (qy - x[a, 1]) * aby + (qz - x[a, 2]) * abz) / (
        abx * abx + aby * aby + abz * abz)
    lam = min(max(lam, 0.0), 1.0)
    ex = x[a, 0] + lam * abx - qx
    ey = x[a, 1] + lam * aby - qy
    ez = x[a, 2] + lam * abz - qz
    return ps[a] + lam * (ps[a + 1] - ps[a]), ex * ex + ey * ey + ez * ez


@njit(cache=True, parallel=True, fastmath=FASTMATH)
def _relative_kernel(q, out, measure, cull, breaks, coef, poly_x, poly_s, coarse, coarse_x,
                     cover2, arc_t, rep_arc, rep_t, frame_r, key_t, key_r, key_w, twisted, cap0,
                     cap1):
    n = q.shape[0]
    K = poly_x.shape[0] - 1
    Kc = coarse.shape[0] - 1
    M = arc_t.shape[0] - 1
    Q = frame_r.shape[0] - 1
    nk = key_t.shape[0]
    for i in prange(n):
        qx, qy, qz = q[i, 0], q[i, 1], q[i, 2]
        # 1-2. nearest coarse vertex, cover test
        best_c, best_d, covered = 0, np.inf, False
        for c in range(Kc + 1):
            d = _dist2(qx, qy, qz, coarse_x, c)
            if d < best_d:
                best_d, best_c = d, c
            covered |= d <= cover2[c]
        if cull and not covered:
            out[i, 0] = out[i, 1] = out[i, 2] = np.nan
            measure[i] = np.inf
            continue
        # nearest dense vertex between the coarse neighbours, then its two segments
        k0 = coarse[max(best_c - 1, 0)]
        k1 = coarse[min(best_c + 1, Kc)]
        k, best_d = k0, np.inf
        for j in range(k0, k1 + 1):
            d = _dist2(qx, qy, qz, poly_x, j)
            if d < best_d:
                best_d, k = d, j
        a = min(max(k - 1, 0), K - 1)
        s, d_a = _segment(qx, qy, qz, poly_x, poly_s, a)
        a2 = min(a + 1, K - 1)
        s2, d_b = _segment(qx, qy, qz, poly_x, poly_s, a2)
        if d_b < d_a:
            s = s2
        lo = poly_s[max(k - 2, 0)]
        hi = poly_s[min(k + 2, K)]
        # 3. Newton on |C(s) - q|^2 / 2
        for _ in range(NEWTON_MAX_STEPS):
            cx, cy, cz, dx, dy, dz, ex, ey, ez = _curve(s, breaks, coef)
            rx, ry, rz = cx - qx, cy - qy, cz - qz
            g = rx * dx + ry * dy + rz * dz
            gn = dx * dx + dy * dy + dz * dz
            H = gn + rx * ex + ry * ey + rz * ez
            if not H > 1e-3 * gn:
                H = gn
            s_new = min(max(s - g / H, lo), hi)
            done = abs(s_new - s) <= NEWTON_TOL
            s = s_new
            if done:
                break
        # 4. frame at the foot point
        cx, cy, cz, dx, dy, dz, ex, ey, ez = _curve(s, breaks, coef)
        inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
        tx, ty, tz = dx * inv, dy * inv, dz * inv
        j, w = _uniform_cell(s, M)
        t = arc_t[j] * (1.0 - w) + arc_t[j + 1] * w
        if rep_arc.shape[0] > 0:
            t = _interp(t, rep_arc, rep_t)
        j, w = _uniform_cell(s, Q)
        rx = frame_r[j, 0] * (1.0 - w) + frame_r[j + 1, 0] * w
        ry = frame_r[j, 1] * (1.0 - w) + frame_r[j + 1, 1] * w
        rz = frame_r[j, 2] * (1.0 - w) + frame_r[j + 1, 2] * w
        rt = rx * tx + ry * ty + rz * tz
        nx, ny, nz = rx - rt * tx, ry - rt * ty, rz - rt * tz
        inv = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx * inv, ny * inv, nz * inv
        bx, by, bz = ty * nz - tz * ny, tz * nx - tx * nz, tx * ny - ty * nx
        if twisted:
            ang = _interp(t, key_t, key_w)
            co, si = math.cos(ang), math.sin(ang)
            nx, ny, nz, bx, by, bz = (co * nx + si * bx, co * ny + si * by, co * nz + si * bz,
                                      co * bx - si * nx, co * by - si * ny, co * bz - si * nz)
        if nk == 1:
            ry_, rz_ = key_r[0, 0], key_r[0, 1]
        else:
            ry_, rz_ = _interp(t, key_t, key_r[:, 0]), _interp(t, key_t, key_r[:, 1])
        # caps: past an end, distance along the end tangent and the offset across it
        px, py, pz = qx - cx, qy - cy, qz - cz
        along = px * tx + py * ty + pz * tz
        u = 2.0 * t - 1.0
        if s <= 0.0:
            u = -1.0 + along / cap0
            px, py, pz = px - along * tx, py - along * ty, pz - along * tz
        elif s >= 1.0:
            u = 1.0 + along / cap1
            px, py, pz = px - along * tx, py - along * ty, pz - along * tz
        a_ = (px * nx + py * ny + pz * nz) / ry_
        b_ = (px * bx + py * by + pz * bz) / rz_
        out[i, 0] = u
        out[i, 1] = a_
        out[i, 2] = b_
        e = max(abs(u) - 1.0, 0.0)
        measure[i] = e * e + a_ * a_ + b_ * b_


@njit(cache=True, parallel=True, fastmath=FASTMATH)
def _near_cover_kernel(p, pad, poly_x, coarse, cover, out):
    for i in prange(p.shape[0]):
        hit = False
        for c in range(coarse.shape[0]):
            r = cover[c] + pad
            if _dist2(p[i, 0], p[i, 1], p[i, 2], poly_x, coarse[c]) <= r * r:
                hit = True
                break
        out[i] = hit


def _threads() -> None:
    """Follow the process's torch thread count (set by the app layer), within numba's pool.
    Starting numba's OpenMP pool resets the OpenMP runtime it shares with torch to all cores,
    so the app's count is put back (measured: torch 1 thread -> 2 after the first call)."""
    n = torch.get_num_threads()
    numba.set_num_threads(max(1, min(n, numba.config.NUMBA_NUM_THREADS)))
    if torch.get_num_threads() != n:
        torch.set_num_threads(n)  # puts back the caller's count


def relative_coordinates(tables: RelativeTables, q: np.ndarray, cull: bool = False
                         ) -> tuple[np.ndarray, np.ndarray]:
    """q (N, 3) float32 or float64 (read as it is: no copy) -> (rel (N, 3) float64, measure (N,)
    float64); float64 arithmetic throughout.

    measure = max(|u| - 1, 0)^2 + a^2 + b^2 (<= 1 inside). With `cull`, points outside the
    cover balls get rel NaN and measure inf without the closest-point solve."""
    if q.dtype not in (np.float32, np.float64):
        q = q.astype(np.float64)
    q = np.ascontiguousarray(q)
    out = np.empty(q.shape, dtype=np.float64)
    measure = np.empty(len(q), dtype=np.float64)
    if len(q):
        _threads()
        T = tables
        _relative_kernel(q, out, measure, bool(cull), T.breaks, T.coef, T.poly_x, T.poly_s,
                         T.coarse, np.ascontiguousarray(T.poly_x[T.coarse]), T.cover ** 2,
                         T.arc_t, T.rep_arc, T.rep_t, T.frame_r, T.key_t, T.key_r, T.key_w,
                         bool(T.twisted), float(T.caps[0]), float(T.caps[1]))
    return out, measure


def near_cover(tables: RelativeTables, points: np.ndarray, pad: float) -> np.ndarray:
    """(N,) bool: the point lies within `pad` of a cover ball (False: farther than `pad` from
    the GC, a conservative test for a box of half-diagonal `pad` centred there)."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    out = np.empty(len(p), dtype=np.bool_)
    if len(p):
        _threads()
        _near_cover_kernel(p, float(pad), tables.poly_x, tables.coarse, tables.cover, out)
    return out
