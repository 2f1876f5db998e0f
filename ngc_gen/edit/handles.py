"""Handle deformation (paper Sec. 4.2): drag handle points, bend the GCs that hold them.

Given handle points on the shape, their targets and a fixed region:
1. estimate one rigid transform (R, t) of the handles onto the targets (Kabsch);
2. give each handle to the GC that holds it nearest that GC's moving end (a handle at a joint
   lies in two GCs; it belongs to the one whose end it drags); the fixed end of a GC is the end
   nearer the fixed region (along the curve, for fixed points inside the GC);
3. for each GC with handles, carry (R, t) to the moving end's point and tangent and join it to
   the unchanged fixed end with a cubic Bezier P0, P0 + alpha T0, P3 - alpha T3, P3 whose arc
   length equals the old curve's (Roulier & Piper): a 1-D root find on alpha (brentq).
   The new curve is a cubic Bezier whatever the old curve was (another degree, a spline):
   that is the paper's method, and a Hermite/Bezier is what the tangent-magnitude search needs;
4. GCs attached to a moving end (a foot on a leg, and what hangs on the foot) follow rigidly.

Keys (radii, twists, in t) and caps are kept, so the cross-sections ride along the new curve.
Frames: the new GC's rotation-minimising frame is anchored at the fixed end (that end's frame is
unchanged); along a non-planar new curve the RMF reaches the moving end with a different roll
than the rigidly moved old end frame (holonomy), so that roll difference is added as a twist
growing linearly from 0 at the fixed end. The moving end's cross-section then turns exactly
with the handles, which is what makes handle points land on their targets and attached GCs fit.
For planar bends the correction is zero and the keys come back unchanged.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import torch
from scipy.optimize import brentq, minimize_scalar
from scipy.spatial.distance import cdist

from ngc_gen.geometry import BezierCurve, GeneralizedCylinder, Key

from .errors import EditError
from .ops import check_array, curve_points_at, min_rotation, rebuild, with_keys_at

OP = "handles"

# 16-point Gauss-Legendre on 64 intervals: a cubic's arc length to ~1e-13 relative
_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
_INTERVALS = 64
_S = ((np.arange(_INTERVALS)[:, None] + (_GL_X[None] + 1) / 2) / _INTERVALS).reshape(-1)
_W = np.tile(_GL_W / 2, _INTERVALS) / _INTERVALS


@dataclass
class HandleSolve:
    """What `deform_by_handles` did: the rigid fit and, per bent GC, its end solve."""

    R: np.ndarray                 # (3, 3) rotation of the handles
    t: np.ndarray                 # (3,) translation: target ~ R handle + t
    residual: float               # max |R h + t - target| over handles (0 for a rigid drag)
    bent: dict = field(default_factory=dict)       # GC name -> {moving_end, alpha, lengths,..}
    followers: dict = field(default_factory=dict)  # follower GC name -> bent GC it follows


# ---- rigid fit -------------------------------------------------------------------------------
def kabsch(src, dst) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rotation R (3, 3) and translation t (3,) with dst ~ src @ R.T + t.

    src, dst: (H, 3). One point (or coincident points) -> a pure translation. Collinear points
    leave the roll about their line free: the smallest rotation between the two lines is used."""
    src, dst = np.asarray(src, np.float64), np.asarray(dst, np.float64)
    ms, md = src.mean(0), dst.mean(0)
    X, Y = src - ms, dst - md
    sv = np.linalg.svd(X, compute_uv=False) if len(X) > 1 else np.zeros(3)
    scale = max(np.abs(src).max(), 1.0)
    if sv[0] <= 1e-12 * scale:
        R = np.eye(3)
    elif len(sv) < 2 or sv[1] <= 1e-9 * sv[0]:  # collinear handles
        d = np.linalg.svd(X)[2][0]
        e = Y.T @ (X @ d)
        if np.linalg.norm(e) <= 1e-12 * scale:
            R = np.eye(3)
        else:
            perp = np.cross(d, np.eye(3)[int(np.argmin(np.abs(d)))])
            R = min_rotation(d, e / np.linalg.norm(e), perp / np.linalg.norm(perp))
    else:
        U, _, Vt = np.linalg.svd(X.T @ Y)
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
        R = Vt.T @ D @ U.T
    return R, md - R @ ms


# ---- Roulier & Piper: cubic of prescribed arc length -----------------------------------------
def cubic_length(ctrl: np.ndarray) -> float:
    """Arc length of the cubic Bezier with control points ctrl (4, 3)."""
    s = _S[:, None]
    d = 3.0 * ((1 - s) ** 2 * (ctrl[1] - ctrl[0]) + 2 * (1 - s) * s * (ctrl[2] - ctrl[1])
               + s ** 2 * (ctrl[3] - ctrl[2]))
    return float(_W @ np.linalg.norm(d, axis=1))


def hermite_of_length(p0, t0, p3, t3, length: float, gc_name: str | None = None,
                      on_unreachable: str = "raise") -> tuple[np.ndarray, float, float]:
    """Cubic Bezier P0, P0 + alpha T0, P3 - alpha T3, P3 of arc length `length`.

    p0, p3: (3,) end points; t0, t3: (3,) unit end tangents (direction of travel). Returns
    (ctrl (4, 3), alpha, achieved length). The smallest root alpha > 0 is bracketed by doubling
    and refined with brentq. A cubic is never shorter than its chord, so ends further apart
    than `length` cannot be joined: EditError, or with on_unreachable="closest" the alpha whose
    length is nearest (with a warning)."""
    p0, t0, p3, t3 = (np.asarray(v, np.float64) for v in (p0, t0, p3, t3))

    def ctrl(alpha):
        return np.stack([p0, p0 + alpha * t0, p3 - alpha * t3, p3])

    def f(alpha):
        return cubic_length(ctrl(alpha)) - length

    chord = float(np.linalg.norm(p3 - p0))
    guess = chord / 3.0  # the uniform-speed straight line when the tangents follow the chord
    if guess > 0 and abs(f(guess)) <= 1e-12 * length:
        return ctrl(guess), guess, cubic_length(ctrl(guess))
    lo, hi = 1e-6 * length, None
    if chord < length and f(lo) < 0:
        a = lo
        while a < 1e3 * length:
            a *= 2.0
            if f(a) >= 0:
                hi = a
                break
            lo = a
    if hi is None:
        if on_unreachable != "closest":
            raise EditError(
                f"the moved end is {chord:.4g} from the fixed end but the curve is "
                f"{length:.4g} long, so no curve of the same arc length joins them (with these "
                f"end tangents)", op=OP, gc=gc_name,
                fix="move the targets closer to the fixed region, stretch the GC first, or "
                    "pass on_unreachable='closest'")
        res = minimize_scalar(lambda a: abs(f(a)), bounds=(1e-2 * length, length),
                              method="bounded")
        alpha = float(res.x)
        got = cubic_length(ctrl(alpha))
        warnings.warn(f"handle deformation of GC '{gc_name}': arc length {length:.4g} is not "
                      f"reachable (chord {chord:.4g}); using the closest, length {got:.4g}",
                      stacklevel=3)
        return ctrl(alpha), alpha, got
    alpha = brentq(f, lo, hi, xtol=1e-15 * length, rtol=1e-14, maxiter=200)
    return ctrl(alpha), alpha, cubic_length(ctrl(alpha))


# ---- frames ----------------------------------------------------------------------------------
def _signed_angle(a: np.ndarray, b: np.ndarray, axis: np.ndarray) -> float:
    """Angle (radians) turning unit vector a to b about unit `axis` (both normal to it)."""
    return math.atan2(float(np.cross(a, b) @ axis), float(a @ b))


def _end_frame(gc: GeneralizedCylinder, end: int, twisted: bool = True) -> np.ndarray:
    """(4, 3) rows C, T, N, B at the curve's start (end=0) or end (end=1)."""
    s = torch.tensor([float(end)], dtype=torch.float64)
    if twisted:
        return torch.cat(gc.frame(s, s)).numpy()
    C, d1, _ = gc.curve.evaluate(s)
    T = d1 / torch.linalg.norm(d1)
    N, B = gc.frame_field.frames(s, T, None)
    return torch.cat([C, T, N, B]).numpy()


def bend_to(gc: GeneralizedCylinder, moving_end: int, R: np.ndarray, t: np.ndarray,
            on_unreachable: str = "raise") -> tuple[GeneralizedCylinder, dict]:
    """Bend `gc` so its `moving_end` (0 start, 1 end) follows the rigid motion (R, t) while the
    other end stays, keeping arc length (see module docstring). Returns (new GC, info)."""
    e = int(moving_end)
    # (C, T) at s = 0 and 1; both curve kinds pass exactly through their first/last point
    ends = [(gc.curve.points[i], _end_frame(gc, end)[1]) for i, end in ((0, 0), (-1, 1))]
    moved = (R @ ends[e][0] + t, R @ ends[e][1])
    (p0, t0), (p3, t3) = (ends[0], moved) if e == 1 else (moved, ends[1])
    ctrl, alpha, got = hermite_of_length(p0, t0, p3, t3, gc.length, gc.name, on_unreachable)
    curve = BezierCurve(ctrl)
    if e == 1:  # fixed start: the RMF starts there from the unchanged up
        new = rebuild(OP, gc, curve=curve, up=gc.up)
    else:  # fixed end: choose the start's up so the RMF arrives at the old end frame
        trial = rebuild(OP, gc, curve=curve, up=R @ gc.up)
        n_new, n_old = _end_frame(trial, 1, False)[2], _end_frame(gc, 1, False)[2]
        T1 = _end_frame(trial, 1, False)[1]
        d = _signed_angle(n_new, n_old, T1)
        T0 = _end_frame(trial, 0, False)[1]
        n0 = _end_frame(trial, 0, False)[2]
        up = math.cos(d) * n0 + math.sin(d) * np.cross(T0, n0)
        new = rebuild(OP, gc, curve=curve, up=up)
    # roll of the moving end: match the rigidly moved old frame by a linear twist ramp
    f_new, f_old = _end_frame(new, e), _end_frame(gc, e)
    roll = math.degrees(_signed_angle(f_new[2], R @ f_old[2], f_new[1]))
    if abs(roll) > 1e-9:
        keys = [Key(k.t, k.radii, k.twist + roll * (k.t if e == 1 else 1.0 - k.t))
                for k in with_keys_at(new, [0.0, 1.0])]
        new = rebuild(OP, new, keys=keys)
    return new, {"moving_end": e, "alpha": float(alpha), "length_old": gc.length,
                 "length_new": new.length, "twist_added": roll}


# ---- which GC, which end ---------------------------------------------------------------------
def _fixed_distances(gc: GeneralizedCylinder, fixed) -> tuple[np.ndarray, bool]:
    """Distances (2,) of the curve's start and end to the fixed region, and whether the GC is
    anchored in it (then it never follows another GC).

    Fixed points inside the GC measure along the curve: (t_min, 1 - t_max) L of their
    parameters, so a GC pinned near its start moves its end even when the start lies deep
    inside a fixed part (far from that part's surface points, as a tail root in a torso).
    Otherwise the straight distances of the curve's ends to the nearest fixed point."""
    if fixed is None:
        return np.array([np.inf, np.inf]), False
    if callable(fixed):
        t = np.linspace(0.0, 1.0, 257)
        m = np.asarray(fixed(curve_points_at(gc, t)), dtype=bool)
        if m.shape != t.shape:
            raise EditError(f"the fixed-region predicate must map (N, 3) points to (N,) bools, "
                            f"got shape {m.shape}", op=OP, gc=gc.name, field="fixed")
        if not m.any():
            return np.array([np.inf, np.inf]), False
        return np.array([t[m].min(), 1.0 - t[m].max()]) * gc.length, True
    lo, hi = gc.bounds()
    near = fixed[((fixed >= lo) & (fixed <= hi)).all(1)]  # the box first: to_relative is dearer
    rel = gc.to_relative(near)
    inside = GeneralizedCylinder.inside_relative(rel)
    if inside.any():
        t = np.clip((rel[inside, 0] + 1.0) / 2.0, 0.0, 1.0)
        return np.array([t.min(), 1.0 - t.max()]) * gc.length, True
    ends = curve_points_at(gc, [0.0, 1.0])
    return cdist(ends, fixed).min(1), False


def _check_inputs(gcs, handles, targets, fixed, on_unreachable):
    if not isinstance(gcs, (list, tuple)) or not gcs or \
            not all(isinstance(g, GeneralizedCylinder) for g in gcs):
        raise EditError("gcs must be a non-empty list of GeneralizedCylinder", op=OP)
    names = [g.name for g in gcs]
    if len(set(names)) != len(names):
        raise EditError(f"GC names must be unique, got {names}", op=OP)
    H = check_array(OP, None, "handles", handles, (-1, 3))
    T = check_array(OP, None, "targets", targets, (-1, 3))
    if len(H) == 0 or H.shape != T.shape:
        raise EditError(f"needs as many targets as handles (at least one), got {H.shape} "
                        f"handles and {T.shape} targets", op=OP, field="targets")
    if fixed is not None and not callable(fixed):
        fixed = check_array(OP, None, "fixed", fixed, (-1, 3))
        if len(fixed) == 0:
            fixed = None
    if on_unreachable not in ("raise", "closest"):
        raise EditError("must be 'raise' or 'closest'", op=OP, field="on_unreachable",
                        value=on_unreachable)
    return H, T, fixed


def deform_by_handles(gcs: list[GeneralizedCylinder], handles, targets,
                      fixed: np.ndarray | Callable | None = None, *,
                      attached: dict[str, list[str]] | None = None,
                      on_unreachable: str = "raise", return_info: bool = False):
    """Move `handles` (H, 3) to `targets` (H, 3) by bending the GCs that hold them.

    fixed: (F, 3) points that must stay (e.g. mesh vertices of the fixed region), or a
    predicate points (N, 3) -> (N,) bool, or None (then the end away from the handles moves).
    attached: optional {bent GC name: [names of GCs that follow it rigidly]}; by default a GC
    follows when one of its curve ends lies inside the moving half of a bent GC, or anywhere
    inside a GC that already follows (transitively), unless it is anchored in the fixed region.
    All handles share one rigid transform; for independent drags call this once per group.
    Returns the list of GCs in input order (unchanged ones are the same objects), and with
    return_info=True also a HandleSolve. Bent GCs are solved independently of each other."""
    H, Tg, fixed = _check_inputs(gcs, handles, targets, fixed, on_unreachable)
    R, t = kabsch(H, Tg)
    residual = float(np.linalg.norm(H @ R.T + t - Tg, axis=1).max())
    scale = float(np.ptp(np.concatenate([H, Tg]), axis=0).max()) or 1.0
    if residual > 1e-6 * scale:
        warnings.warn(f"targets are not a rigid motion of the handles (best rigid fit misses by "
                      f"{residual:.3g}); handles will land on the fitted motion", stacklevel=2)

    # relative coordinates of every handle in every GC: (K, H, 3)
    rel = np.stack([g.to_relative(H) for g in gcs])
    u = rel[..., 0]
    measure = np.clip(np.abs(u) - 1, 0, None) ** 2 + rel[..., 1] ** 2 + rel[..., 2] ** 2
    inside = measure <= 1.0
    far = measure.min(0) > 4.0
    if far.any():
        j = int(np.argmax(far))
        raise EditError(f"handle {j} at {np.round(H[j], 4).tolist()} lies in no GC (nearest "
                        f"is '{gcs[int(measure[:, j].argmin())].name}')", op=OP,
                        field="handles", fix="pick handles on the shape's surface")
    holds = inside | (~inside.any(0) & (measure == measure.min(0)))  # outside all: nearest GC

    # fixed / moving end of every GC that holds a handle
    dist, anchored = zip(*(_fixed_distances(g, fixed) for g in gcs))
    dist, anchored = np.stack(dist), np.array(anchored)
    u_mean = np.where(holds, u, 0).sum(1) / np.maximum(holds.sum(1), 1)
    moving = np.where(dist[:, 0] < dist[:, 1], 1,
                      np.where(dist[:, 1] < dist[:, 0], 0, (u_mean >= 0).astype(int)))
    # each handle goes to the holding GC where it is nearest the moving end (in u)
    to_end = np.where(moving[:, None] == 1, np.clip(1 - u, 0, None), np.clip(u + 1, 0, None))
    owner = np.where(holds, to_end, np.inf).argmin(0)
    bent_idx = sorted(set(owner.tolist()))

    out = list(gcs)
    info = HandleSolve(R, t, residual)
    queue = []  # (index, old GC, moving end or None for followers, R_f, t_f, root name)
    for k in bent_idx:
        old = gcs[k]
        new, meta = bend_to(old, int(moving[k]), R, t, on_unreachable)
        meta["handles"] = np.flatnonzero(owner == k).tolist()
        out[k] = new
        info.bent[old.name] = meta
        fo, fn = _end_frame(old, meta["moving_end"]), _end_frame(new, meta["moving_end"])
        Rf = fn[1:].T @ fo[1:]  # old (T, N, B) -> new (T, N, B)
        queue.append((k, old, meta["moving_end"], Rf, fn[0] - Rf @ fo[0], old.name))

    _move_followers(gcs, out, info, queue, set(bent_idx), anchored, attached)
    return (out, info) if return_info else out


def _move_followers(gcs, out: list, info: "HandleSolve", queue: list, moved: set, anchored,
                    attached: dict[str, list[str]] | None) -> None:
    """The GCs that follow the bent ones rigidly (`deform_by_handles`' `attached`, or by
    default those with a curve end in the moving half of a bent GC, transitively, unless
    anchored), written into `out`; `queue`: (index, old GC, moving end, R_f, t_f, root name)
    of every bent GC."""
    index = {g.name: i for i, g in enumerate(gcs)}
    if attached is not None:
        for root, names in attached.items():
            if root not in info.bent:
                raise EditError(f"names GC '{root}', which is not bent by these handles "
                                f"(bent: {sorted(info.bent)})", op=OP, field="attached")
            _, _, _, Rf, tf, _ = next(q for q in queue if q[5] == root)
            for name in names:
                if name not in index:
                    raise EditError(f"unknown GC '{name}'; GCs are {sorted(index)}", op=OP,
                                    field="attached")
                i = index[name]
                if i not in moved:
                    out[i] = gcs[i].transformed(Rf, tf)
                    info.followers[name] = root
                    moved.add(i)
        queue = []
    while queue:
        k, old, e, Rf, tf, root = queue.pop(0)
        for i, g in enumerate(gcs):
            if i in moved or anchored[i]:
                continue
            ends = curve_points_at(g, [0.0, 1.0])
            r = old.to_relative(ends)
            hit = GeneralizedCylinder.inside_relative(r)
            if e is not None:
                hit &= (r[:, 0] > 0) if e == 1 else (r[:, 0] < 0)
            if hit.any():
                out[i] = g.transformed(Rf, tf)
                info.followers[g.name] = root
                moved.add(i)
                queue.append((i, g, None, Rf, tf, root))
