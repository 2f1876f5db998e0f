"""Relative coordinates of many points in one fused pass (numba, all CPU cores).

Per point, in float64 whatever the input dtype (docs/gcs.md):
1. seed: the nearest vertex of a coarse polyline (every `stride`-th vertex of the dense one),
   then the nearest dense vertex between that vertex's two coarse neighbours. Where q is close
   enough to the coarse vertex for |C(t) - q|^2 to be convex over that window
   (`RelativeTables.convex`, from a curvature bound) the distances fall, then rise, and a descent
   from the coarse vertex finds that vertex in ~3 steps; elsewhere all 2 stride + 1 are scanned.
   The seed is the root of f' = (C - q).C' interpolated between that vertex and its neighbour
   (tabled C'): O(h^2) close, no curve evaluation;
2. cull (optional): a point outside every coarse cover ball is outside the GC, so it skips the
   rest (`GeneralizedCylinder.cover_radii` says why the balls enclose the GC);
3. Newton on f(s) = |C(s) - q|^2 / 2 from the seed, kept within two dense segments each side,
   until a step moves s by at most NEWTON_TOL: two steps reach rounding for ~90% of points, one
   for the rest. Where f'' <= 0 (q past the centre of curvature) it takes a Gauss-Newton step.
   C and C' at the foot come from the last evaluation by Taylor (no extra evaluation);
4. global: that Newton finds a local minimum near the seed, which for a point nearly as close
   to another arc (a tight bend, a curve passing close to itself) may not be the closest point.
   A certificate rules out most of the curve at once: around a stationary foot t, f(t') >=
   f(t) + f''(t) d^2 / 2 - (kappa + D |C_ttt|) d^3 / 6 with d = |t' - t| in arc length and D
   = |C(t) - q| (f'' = 1 + (C - q).C_tt), so nothing within rho = 3 f''(t) / (kappa + D
   |C_ttt|) of it is nearer (bounds over the nearest coarse vertex's span, `span_bounds`).
   Every coarse ball (`reach`) not wholly inside that range and nearer than D is then searched:
   each of its segments whose chord, less the arc's bulge (`segment_bulge`), comes nearer than
   the best distance so far gets its own Newton. The foot is the global closest point for
   every point; most points have no ball to search (a branch-free pass over the coarse balls);
5. frame, twist, radii and caps at the foot point as `GeneralizedCylinder` defines them: one
   key-cell search for twist and radii, reciprocals instead of divisions where they are
   constants, sin and cos of the twist by fdlibm's polynomials (a third of libm's cost).

A torch implementation of the same steps would run ~60 small kernels per chunk of points, each
a pass over memory; fused, a point costs ~160 ns on one core (bench/geometry.py), about a third
each for the seed, Newton and the rest (the global step ~10%). Results match the float64
definition to rounding (round trip ~1e-14 on points inside, float64; foot points within 1e-14 of
a brute force's, `closest_check`); rel is written in the caller's dtype directly.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import torch
from numba import njit, prange

from .relative_tables import SPAN, RelativeTables

NEWTON_MAX_STEPS = 8
# stop once a step moves s by at most this: Newton converges quadratically from the O(h^2) seed,
# so after a step of 1e-7 s is within ~C 1e-14 of the root (C = |f'''| / 2|f''|, O(1)): two
# steps for most points. Waiting for an exactly zero step instead ended in rounding ping-pong
# for a third of the points (8 steps)
NEWTON_TOL = 1e-7
# the kernels may fuse a * b + c into one rounding (FMA): a few percent; per point the same
# compiled code runs whatever the batch, so results stay reproducible
FASTMATH = {"contract"}
@njit(cache=True, fastmath=FASTMATH)
def _bisect(x, xp):
    """The cell lo of increasing xp with xp[lo] <= x < xp[lo + 1] (0 below xp[0], the last
    cell from xp[-1] on)."""
    lo, hi = 0, xp.shape[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True, fastmath=FASTMATH)
def _piece(s, breaks):
    """Index of the polynomial piece holding s (clamped)."""
    return 0 if breaks.shape[0] == 2 else _bisect(s, breaks)


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
    lo = _bisect(x, xp)
    w = (x - xp[lo]) / (xp[lo + 1] - xp[lo])
    return fp[lo] * (1.0 - w) + fp[lo + 1] * w


@njit(cache=True, fastmath=FASTMATH)
def _uniform_cell(x, M):
    """Cell index and weight of x in linspace(0, 1, M + 1), clamped."""
    xs = min(max(x, 0.0), 1.0) * M
    i = min(int(xs), M - 1)
    return i, xs - i


@njit(cache=True, fastmath=FASTMATH)
def _key_cell(x, xp, inv_dx):
    """Cell index and weight of x in the increasing xp (at least 2 entries), clamped; inv_dx the
    reciprocal cell widths. One search serves twist and both radii."""
    n = xp.shape[0]
    if x <= xp[0]:
        return 0, 0.0
    if x >= xp[n - 1]:
        return n - 2, 1.0
    lo = _bisect(x, xp)
    return lo, (x - xp[lo]) * inv_dx[lo]


# fdlibm's kernel polynomials for sin and cos on [-pi/4, pi/4] (error < 1 ulp there) and the
# two-part pi/2 of its argument reduction
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
_PIO2_1, _PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11


@njit(cache=True, fastmath=FASTMATH)
def _sincos(x):
    """(sin x, cos x) to about 1 ulp for |x| < 1e5 (twist angles): a third of libm's cost for
    the pair."""
    k = round(x * (2.0 / math.pi))
    r = (x - k * _PIO2_1) - k * _PIO2_1T
    z = r * r
    sn = r + z * r * (_S[0] + z * (_S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * _S[5])))))
    hz = 0.5 * z
    w = 1.0 - hz
    cs = w + (((1.0 - w) - hz) + z * z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (
        _C[3] + z * (_C[4] + z * _C[5]))))))
    m = int(k) & 3  # quadrant, without branches (the twist varies from point to point)
    swap = (m & 1) == 1
    return ((cs if swap else sn) * (1.0 - (m & 2)),
            (sn if swap else cs) * (1.0 - ((m + 1) & 2)))


@njit(cache=True, fastmath=FASTMATH)
def _dist2(qx, qy, qz, x, k):
    ax = qx - x[k, 0]
    ay = qy - x[k, 1]
    az = qz - x[k, 2]
    return ax * ax + ay * ay + az * az


@njit(cache=True, fastmath=FASTMATH)
def _fprime(qx, qy, qz, x, dx, k):
    """f'(s_k) = (C(s_k) - q).C'(s_k) at dense vertex k."""
    return (x[k, 0] - qx) * dx[k, 0] + (x[k, 1] - qy) * dx[k, 1] + (x[k, 2] - qz) * dx[k, 2]


@njit(cache=True, fastmath=FASTMATH, inline="always")  # (a call: 5 ns a point)
def _newton(qx, qy, qz, s, lo, hi, breaks, coef):
    """Newton on f(s) = |C(s) - q|^2 / 2 from s, kept within [lo, hi], until a step moves s by
    at most NEWTON_TOL; where f'' <= 0 (q past the centre of curvature) a Gauss-Newton step.
    Returns s, the last step, C, C', C'' where the last step started, and f'' (H) and |C'|^2
    (gn) there."""
    step = 0.0
    H = gn = 1.0
    cx = cy = cz = dx = dy = dz = ex = ey = ez = 0.0
    for _ in range(NEWTON_MAX_STEPS):
        cx, cy, cz, dx, dy, dz, ex, ey, ez = _curve(s, breaks, coef)
        rx, ry, rz = cx - qx, cy - qy, cz - qz
        g = rx * dx + ry * dy + rz * dz
        gn = dx * dx + dy * dy + dz * dz
        H = gn + rx * ex + ry * ey + rz * ez
        s_new = min(max(s - g / (H if H > 1e-3 * gn else gn), lo), hi)
        step = s_new - s
        s = s_new
        if abs(step) <= NEWTON_TOL:
            break
    return s, step, cx, cy, cz, dx, dy, dz, ex, ey, ez, H, gn


@njit(cache=True, fastmath=FASTMATH)
def _nearer_foot(qx, qy, qz, s, D2, cert_lo, cert_hi, dc, breaks, coef, poly_x, poly_s,
                 owned, reach, chord, inv_chord, bulge):
    """The global closest point, given a local one (parameter s, squared distance D2) and the
    segments cert_lo <= j < cert_hi known to hold nothing nearer: every other segment whose arc
    may come nearer than the best distance so far (its coarse ball first, then its chord less
    its bulge) gets a Newton search of its own. dc: squared distances to the coarse vertices.
    Returns (s, squared distance, whether s moved)."""
    D = math.sqrt(D2)
    moved = False
    for c in range(reach.shape[0]):
        j0, j1 = owned[c], owned[c + 1]
        if j0 >= cert_lo and j1 <= cert_hi:
            continue
        r = D + reach[c]
        if dc[c] >= r * r:
            continue
        dA = _dist2(qx, qy, qz, poly_x, j0)
        for j in range(j0, j1):
            dB = _dist2(qx, qy, qz, poly_x, j + 1)
            if j < cert_lo or j >= cert_hi:
                cj = chord[j]
                x = (dA - dB + cj * cj) * (0.5 * inv_chord[j])  # along the chord from x_j
                if x <= 0.0:
                    e2, lam = dA, 0.0
                elif x >= cj:
                    e2, lam = dB, 1.0
                else:
                    e2, lam = dA - x * x, x * inv_chord[j]
                lb = D + bulge[j]
                if e2 < lb * lb:
                    a, b = poly_s[j], poly_s[j + 1]
                    sj = _newton(qx, qy, qz, a + lam * (b - a), a, b, breaks, coef)[0]
                    cx, cy, cz = _curve(sj, breaks, coef)[:3]
                    d2 = (cx - qx) ** 2 + (cy - qy) ** 2 + (cz - qz) ** 2
                    if d2 < D2:
                        s, D2, D, moved = sj, d2, math.sqrt(d2), True
            dA = dB
    return s, D2, moved


POINTS_PER_TASK = 256  # points per parallel task (a task reuses one scratch row)


@njit(cache=True, parallel=True, fastmath=FASTMATH)
def _relative_kernel(q, out, measure, cull, breaks, coef, poly_x, poly_s, poly_d, coarse,
                     coarse_x, cover2, convex2, chord, inv_chord, bulge, owned, reach, span_k,
                     span_dk, arc_t, rep_arc, rep_t, frame_r, key_t, key_dt, key_r, key_w,
                     twisted, inv_cap0, inv_cap1, length):
    n = q.shape[0]
    K = poly_x.shape[0] - 1
    Kc = coarse.shape[0] - 1
    M = arc_t.shape[0] - 1
    Q = frame_r.shape[0] - 1
    nk = key_t.shape[0]
    with_measure = measure.shape[0] > 0
    # f(t') >= f(t) + f''(t) d^2 / 2 - (kappa + D |C_ttt|) d^3 / 6 for d = |t' - t| (f'(t) = 0)
    rho_scale = 0.98 * 3.0 * K / length
    for task in prange((n + POINTS_PER_TASK - 1) // POINTS_PER_TASK):
        dc = np.empty(Kc + 1)
        for i in range(task * POINTS_PER_TASK, min(n, (task + 1) * POINTS_PER_TASK)):
            qx, qy, qz = float(q[i, 0]), float(q[i, 1]), float(q[i, 2])
            # 1-2. nearest coarse vertex, cover test
            best_c, best_d, covered = 0, np.inf, False
            for c in range(Kc + 1):
                d = _dist2(qx, qy, qz, coarse_x, c)
                dc[c] = d
                if d < best_d:
                    best_d, best_c = d, c
                if cull:  # (a compare and an or per vertex in the hot loop otherwise)
                    covered |= d <= cover2[c]
            if cull and not covered:
                out[i, 0] = out[i, 1] = out[i, 2] = np.nan
                if with_measure:
                    measure[i] = np.inf
                continue
            # nearest dense vertex between the coarse neighbours
            k0 = coarse[max(best_c - 1, 0)]
            k1 = coarse[min(best_c + 1, Kc)]
            if best_d < convex2[best_c]:
                # f convex over the window: the vertex distances fall, then rise, so descent
                # from the coarse vertex stops at their minimum (3 steps on average instead of
                # 2 stride)
                k = coarse[best_c]
                if k < k1 and _dist2(qx, qy, qz, poly_x, k + 1) < best_d:
                    while k < k1:
                        d = _dist2(qx, qy, qz, poly_x, k + 1)
                        if d >= best_d:
                            break
                        best_d, k = d, k + 1
                else:
                    while k > k0:
                        d = _dist2(qx, qy, qz, poly_x, k - 1)
                        if d >= best_d:
                            break
                        best_d, k = d, k - 1
            else:
                k, best_d = k0, np.inf
                for j in range(k0, k1 + 1):
                    d = _dist2(qx, qy, qz, poly_x, j)
                    if d < best_d:
                        best_d, k = d, j
            # seed: the root of f' = (C - q).C' interpolated linearly between the vertex and its
            # neighbour on the foot's side (f' known there from the tables: no curve evaluation)
            gk = _fprime(qx, qy, qz, poly_x, poly_d, k)
            j = min(k + 1, K) if gk < 0.0 else max(k - 1, 0)
            den = gk - _fprime(qx, qy, qz, poly_x, poly_d, j)
            lam = min(max(gk / den, 0.0), 1.0) if den != 0.0 else 0.0
            s = poly_s[k] + lam * (poly_s[j] - poly_s[k])
            klo, khi = max(k - 2, 0), min(k + 2, K)
            lo, hi = poly_s[klo], poly_s[khi]
            # 3. Newton from the seed, within two dense segments each side. The last step moves
            # s by at most NEWTON_TOL, so C, C' there follow from the last evaluation by Taylor:
            # what is left out, step^2 |C'''| / 2 in C', is of the order of the error that step
            # leaves in s
            s, step, cx, cy, cz, dx, dy, dz, ex, ey, ez, H, gn = _newton(
                qx, qy, qz, s, lo, hi, breaks, coef)
            converged = abs(step) <= NEWTON_TOL
            if converged:
                h2 = 0.5 * step
                cx += step * (dx + h2 * ex)
                cy += step * (dy + h2 * ey)
                cz += step * (dz + h2 * ez)
                dx += step * ex
                dy += step * ey
                dz += step * ez
            else:  # not converged in NEWTON_MAX_STEPS
                cx, cy, cz, dx, dy, dz, ex, ey, ez = _curve(s, breaks, coef)
            j, w = _uniform_cell(s, M)
            t = arc_t[j] * (1.0 - w) + arc_t[j + 1] * w
            # 4. the global closest point. Around a stationary s (or an end the curve leaves q
            # from) nothing within rho in arc length is nearer where f = |C - q|^2 / 2 stays
            # convex: f''(t') >= f''(t) - |t' - t| (kappa + D |C_ttt|) in arc length t
            # (f'' = 1 + (C - q).C_tt), with the bounds of the coarse vertex's span. The other
            # segments are searched where they might hold a nearer point
            D2 = (cx - qx) ** 2 + (cy - qy) ** 2 + (cz - qz) ** 2
            D = math.sqrt(D2)
            span_lo = owned[max(best_c - SPAN, 0)]
            span_hi = owned[min(best_c + SPAN + 1, Kc + 1)]
            cert_lo = cert_hi = 0
            if converged and H > 0.0 and (s > lo or klo == 0) and (s < hi or khi == K):
                u = t * K  # in segments, and rho too:
                du = rho_scale * H / (gn * (span_k[best_c] + D * span_dk[best_c]))
                if span_lo <= u <= span_hi:
                    a = u - du
                    b = min(u + du, span_hi)
                    cert_lo = span_lo if a <= span_lo else int(a) + 1
                    cert_hi = max(int(b), cert_lo)
            # is any coarse ball not wholly certified nearer than D? (no branches: most points
            # have none, and then nothing more to do)
            look = False
            for c in range(Kc + 1):
                r = D + reach[c]
                look |= (dc[c] < r * r) & ((owned[c] < cert_lo) | (owned[c + 1] > cert_hi))
            moved = False
            if look:
                s, D2, moved = _nearer_foot(qx, qy, qz, s, D2, cert_lo, cert_hi, dc, breaks,
                                            coef, poly_x, poly_s, owned, reach, chord,
                                            inv_chord, bulge)
            if moved:
                cx, cy, cz, dx, dy, dz, ex, ey, ez = _curve(s, breaks, coef)
                j, w = _uniform_cell(s, M)
                t = arc_t[j] * (1.0 - w) + arc_t[j + 1] * w
            # 5. frame at the foot point
            inv = 1.0 / math.sqrt(dx * dx + dy * dy + dz * dz)
            tx, ty, tz = dx * inv, dy * inv, dz * inv
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
            # twist and radii from one key cell
            j, w, j1 = 0, 0.0, 0
            if nk > 1:
                j, w = _key_cell(t, key_t, key_dt)
                j1 = j + 1
            if twisted:
                si, co = _sincos(key_w[j] * (1.0 - w) + key_w[j1] * w)
                nx, ny, nz, bx, by, bz = (co * nx + si * bx, co * ny + si * by, co * nz + si * bz,
                                          co * bx - si * nx, co * by - si * ny, co * bz - si * nz)
            ry_ = key_r[j, 0] * (1.0 - w) + key_r[j1, 0] * w
            rz_ = key_r[j, 1] * (1.0 - w) + key_r[j1, 1] * w
            # caps: past an end, distance along the end tangent and the offset across it
            px, py, pz = qx - cx, qy - cy, qz - cz
            along = px * tx + py * ty + pz * tz
            u = 2.0 * t - 1.0
            if s <= 0.0:
                u = -1.0 + along * inv_cap0
                px, py, pz = px - along * tx, py - along * ty, pz - along * tz
            elif s >= 1.0:
                u = 1.0 + along * inv_cap1
                px, py, pz = px - along * tx, py - along * ty, pz - along * tz
            a_ = (px * nx + py * ny + pz * nz) / ry_
            b_ = (px * bx + py * by + pz * bz) / rz_
            out[i, 0] = u
            out[i, 1] = a_
            out[i, 2] = b_
            if with_measure:
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


def relative_coordinates(tables: RelativeTables, q: np.ndarray, cull: bool = False,
                         dtype=np.float64, with_measure: bool = True
                         ) -> tuple[np.ndarray, np.ndarray]:
    """q (N, 3) float32 or float64 (read as it is: no copy) -> (rel (N, 3) `dtype`, measure
    (N,) float64); float64 arithmetic throughout, rel rounded to `dtype` as it is written.

    measure = max(|u| - 1, 0)^2 + a^2 + b^2 (<= 1 inside); empty without `with_measure`.
    With `cull`, points outside the cover balls get rel NaN and measure inf without the
    closest-point solve."""
    if q.dtype not in (np.float32, np.float64):
        q = q.astype(np.float64)
    q = np.ascontiguousarray(q)
    out = np.empty(q.shape, dtype=dtype)
    measure = np.empty(len(q) if with_measure else 0, dtype=np.float64)
    if len(q):
        _threads()
        T = tables
        key_dt = 1.0 / np.diff(T.key_t) if len(T.key_t) > 1 else np.ones(1)
        _relative_kernel(q, out, measure, bool(cull), T.breaks, T.coef, T.poly_x, T.poly_s,
                         T.poly_d, T.coarse, np.ascontiguousarray(T.poly_x[T.coarse]),
                         T.cover ** 2, T.convex ** 2, T.chord,
                         1.0 / np.maximum(T.chord, 1e-300), T.bulge,
                         T.owned, T.reach, T.span_k, T.span_dk, T.arc_t, T.rep_arc, T.rep_t,
                         T.frame_r, T.key_t, key_dt, T.key_r, T.key_w, bool(T.twisted),
                         1.0 / float(T.caps[0]), 1.0 / float(T.caps[1]), float(T.length))
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
