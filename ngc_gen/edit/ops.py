"""Pure edits of one generalized cylinder: GC -> new GC (docs/editing.md).

An NGC's SDF lives in the GC's relative coordinates (u, a, b), so changing the GC deforms the
shape while the neural codes stay untouched. Every op validates its arguments first and raises
an `EditError` naming the op, the GC and the bad value; GCs are immutable, so the input GC is
never changed.

Conventions shared by all ops:
- t in [0, 1] is the GC's parameter as the network sees it (u = 2t - 1; the keys' t): normalised
  arc length, unless a `stretch` stored a `reparam` map from t to arc length. Twist is in degrees.
- Where an edit changes the curve's start tangent, the GC's `up` is carried along by the
  smallest rotation taking the old start tangent to the new one, so the cross-section frame
  follows the edit instead of staying pinned to a world axis (and `up` never ends up parallel
  to the curve). When the start tangent is unchanged, `up` is kept as it was.
"""
from __future__ import annotations

import inspect
import math
from typing import Callable, Iterable

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.geometry import GeneralizedCylinder, GeometryError, Key, SplineCurve

from .errors import EditError

KEY_TOL = 1e-6  # keys closer than this in t are the same key


# ---- validation ------------------------------------------------------------------------------
def _name(gc) -> str | None:
    return getattr(gc, "name", None)


def check_gc(op: str, gc) -> GeneralizedCylinder:
    if not isinstance(gc, GeneralizedCylinder):
        raise EditError(f"expects a GeneralizedCylinder, got {type(gc).__name__}", op=op)
    return gc


def check_t(op: str, gc, field: str, t) -> float:
    """A normalised arc length: a finite number in [0, 1]."""
    try:
        v = float(t)
    except (TypeError, ValueError):
        raise EditError("must be a number in [0, 1]", op=op, gc=_name(gc), field=field,
                        value=t) from None
    if not (0.0 <= v <= 1.0):  # also rejects NaN
        raise EditError("must lie in [0, 1] (normalised arc length along the curve)", op=op,
                        gc=_name(gc), field=field, value=t,
                        fix="give t between 0 (curve start) and 1 (curve end)")
    return v


def check_range(op: str, gc, t0, t1, fix: str = "give t0 < t1") -> tuple[float, float]:
    """A non-empty range 0 <= t0 < t1 <= 1 of normalised arc length."""
    t0, t1 = check_t(op, gc, "t0", t0), check_t(op, gc, "t1", t1)
    if not t0 < t1:
        raise EditError(f"the range [t0, t1] = [{t0}, {t1}] is empty", op=op, gc=_name(gc),
                        field="t1", value=t1, fix=fix)
    return t0, t1


def check_number(op: str, gc, field: str, x, positive: bool = False) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise EditError("must be a number", op=op, gc=_name(gc), field=field, value=x) from None
    if not math.isfinite(v):
        raise EditError("must be finite (got NaN or inf)", op=op, gc=_name(gc), field=field,
                        value=x)
    if positive and v <= 0.0:
        raise EditError("must be positive", op=op, gc=_name(gc), field=field, value=x,
                        fix="use a factor > 0 (1 leaves the GC unchanged)")
    return v


def check_array(op: str, gc, field: str, x, shape: tuple) -> np.ndarray:
    """A finite float64 array of the given shape (-1 = any length)."""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise EditError(f"must be numbers of shape {shape}", op=op, gc=_name(gc), field=field,
                        value=x) from None
    if a.ndim != len(shape) or any(s != -1 and s != n for s, n in zip(shape, a.shape)):
        raise EditError(f"must have shape {shape}, got {a.shape}", op=op, gc=_name(gc),
                        field=field)
    if not np.all(np.isfinite(a)):
        raise EditError("contains NaN or inf", op=op, gc=_name(gc), field=field, value=a)
    return a


def check_factor(op: str, gc, field: str, factor) -> np.ndarray:
    """A positive scale, one number or a pair (r_y, r_z) -> (2,) array."""
    try:
        f = None if isinstance(factor, str) else np.asarray(factor, dtype=np.float64)
    except (TypeError, ValueError):
        f = None
    if f is None or f.ndim > 1 or f.size not in (1, 2):
        raise EditError("must be one number or a pair [f_y, f_z]", op=op, gc=_name(gc),
                        field=field, value=factor)
    f = np.broadcast_to(f.reshape(-1), (2,)).copy()
    if not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise EditError("must be positive and finite", op=op, gc=_name(gc), field=field,
                        value=factor, fix="use a factor > 0 (1 leaves the radii unchanged)")
    return f


def rebuild(op: str, gc: GeneralizedCylinder, **parts) -> GeneralizedCylinder:
    """gc.replace(**parts), turning a geometry error of the result into an EditError."""
    try:
        return gc.replace(**parts)
    except GeometryError as e:
        raise EditError(f"the edited GC is invalid: {str(e).split(': ', 1)[-1]}", op=op,
                        gc=gc.name, field=e.field, fix="use a smaller edit") from None


# ---- curve helpers ---------------------------------------------------------------------------
def tangent(curve, s) -> np.ndarray:
    """Unit tangents (N, 3) of `curve` at its own parameters s (N,); NaN where it stops."""
    d1 = curve.evaluate(torch.as_tensor(np.atleast_1d(s), dtype=torch.float64))[1].numpy()
    n = np.linalg.norm(d1, axis=1, keepdims=True)
    return d1 / np.where(n > 0, n, np.nan)


def min_rotation(a: np.ndarray, b: np.ndarray, fallback_axis: np.ndarray) -> np.ndarray:
    """Smallest rotation (..., 3, 3) taking unit vector a to unit vector b (each (..., 3)).

    For b = -a the axis is ambiguous: turn 180 degrees about `fallback_axis` (unit, normal to a)."""
    a, b, f = np.broadcast_arrays(*(np.asarray(x, np.float64) for x in (a, b, fallback_axis)))
    v, c = np.cross(a, b), (a * b).sum(-1)
    vx = np.zeros(v.shape + (3,))
    vx[..., 0, 1], vx[..., 0, 2], vx[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    vx = vx - np.swapaxes(vx, -1, -2)
    flip = c < -1.0 + 1e-12
    turn = np.eye(3) + vx + vx @ vx / np.where(flip, 1.0, 1.0 + c)[..., None, None]
    half = 2.0 * f[..., :, None] * f[..., None, :] - np.eye(3)
    return np.where(flip[..., None, None], half, turn)


def carry_up(gc: GeneralizedCylinder, curve) -> np.ndarray:
    """gc.up carried to `curve` by the smallest rotation between the old and new start tangents."""
    a, b = tangent(gc.curve, [0.0])[0], tangent(curve, [0.0])[0]
    if not np.all(np.isfinite(b)) or np.linalg.norm(a - b) < 1e-12:  # (a stopped curve fails
        return gc.up                                                 # its own check later)
    n0 = gc.up - (gc.up @ a) * a
    return min_rotation(a, b, n0 / np.linalg.norm(n0)) @ gc.up


def curve_points_at(gc: GeneralizedCylinder, t) -> np.ndarray:
    """Curve points (N, 3) at normalised arc lengths t (N,)."""
    s = gc.arc.s_of_t(torch.as_tensor(np.atleast_1d(t), dtype=torch.float64))
    return gc.curve.evaluate(s)[0].numpy()


# ---- keys ------------------------------------------------------------------------------------
def key_at(gc: GeneralizedCylinder, t: float) -> Key:
    """The GC's profile at t as a Key (radii and twist interpolated as the GC does)."""
    tt = torch.tensor([t], dtype=torch.float64)
    r = gc.radii_at(tt)[0].tolist()
    return Key(float(t), (r[0], r[1]), math.degrees(float(gc.twist_at(tt)[0])))


def with_keys_at(gc: GeneralizedCylinder, ts: Iterable[float]) -> list[Key]:
    """The GC's keys plus a key at each t in ts that has none within KEY_TOL.

    Inserted keys carry the interpolated profile, so the GC's shape is unchanged by them."""
    keys = list(gc.keys)
    for t in ts:
        if all(abs(k.t - t) > KEY_TOL for k in keys):
            keys.append(key_at(gc, t))
    return sorted(keys, key=lambda k: k.t)


def _key_index(keys: list[Key], t: float) -> int:
    return min(range(len(keys)), key=lambda i: abs(keys[i].t - t))


def _edit_keys(op: str, gc: GeneralizedCylinder, t, falloff, fn, verb: str) -> list[Key]:
    """`fn` applied to every key (t = None, no falloff allowed) or to the key at t."""
    if t is None:
        if falloff is not None:
            raise EditError(f"needs a key t (t = None {verb} every key)", op=op, gc=gc.name,
                            field="falloff", value=falloff)
        return [fn(k) for k in gc.keys]
    return _edit_key(op, gc, t, falloff, fn)


def _edit_key(op: str, gc, t, falloff, change: Callable[[Key], Key]) -> list[Key]:
    """Insert a key at t (and pins at t -/+ falloff), then replace the key at t by change(key)."""
    t = check_t(op, gc, "t", t)
    pins = []
    if falloff is not None:
        w = check_number(op, gc, "falloff", falloff, positive=True)
        pins = [p for p in (t - w, t + w) if 0.0 < p < 1.0]
    keys = with_keys_at(gc, [t, *pins])
    i = _key_index(keys, t)
    keys[i] = change(keys[i])
    return keys


# ---- ops -------------------------------------------------------------------------------------
def move_points(gc: GeneralizedCylinder, indices, offsets) -> GeneralizedCylinder:
    """Bend: move curve control points (Bezier) or through-points (spline).

    indices: int or (K,) ints (negative counts from the end, as in Python); offsets: (3,) for
    all of them or (K, 3). Keys stay at their t, so radii and twists follow the new curve."""
    op = "move_points"
    check_gc(op, gc)
    n = len(gc.curve.points)
    idx = np.atleast_1d(np.asarray(indices))
    if idx.ndim != 1 or idx.size == 0 or idx.dtype.kind not in "iu":
        raise EditError("must be one int or a list of ints", op=op, gc=gc.name,
                        field="indices", value=indices)
    bad = idx[(idx < -n) | (idx >= n)]
    if len(bad):
        raise EditError(f"unknown control point index; this {gc.curve.kind} curve has {n} "
                        f"points (indices 0..{n - 1}, or -{n}..-1)", op=op, gc=gc.name,
                        field="indices", value=bad)
    idx = idx % n
    if len(np.unique(idx)) != len(idx):
        raise EditError("lists a control point twice", op=op, gc=gc.name, field="indices",
                        value=indices, fix="give each point once with its total offset")
    try:
        off = None if isinstance(offsets, str) else np.asarray(offsets, dtype=np.float64)
    except (TypeError, ValueError):
        off = None
    if off is None or off.shape not in ((3,), (len(idx), 3)):
        raise EditError(f"must have shape (3,) or ({len(idx)}, 3)", op=op, gc=gc.name,
                        field="offsets", value=offsets)
    off = check_array(op, gc, "offsets", np.broadcast_to(off, (len(idx), 3)), (-1, 3))
    pts = gc.curve.points.copy()
    pts[idx] += off
    try:
        curve = gc.curve.with_points(pts)
    except GeometryError as e:
        raise EditError(f"the moved curve is invalid: {e}", op=op, gc=gc.name,
                        fix="do not move points onto each other") from None
    return rebuild(op, gc, curve=curve, up=carry_up(gc, curve))


def rigid(gc: GeneralizedCylinder, R, t) -> GeneralizedCylinder:
    """Rigid motion x -> R x + t of the whole GC; R (3, 3) a proper rotation, t (3,)."""
    op = "rigid"
    check_gc(op, gc)
    R = check_array(op, gc, "R", R, (3, 3))
    t = check_array(op, gc, "t", t, (3,))
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) <= 0:
        raise EditError("is not a rotation (R R^T = I, det R = +1)", op=op, gc=gc.name,
                        field="R", value=R, fix="give an orthonormal matrix without reflection")
    return gc.transformed(R, t)


def rotate(gc: GeneralizedCylinder, axis, degrees, pivot=None) -> GeneralizedCylinder:
    """Rotate the GC by `degrees` about `axis` (3,) through `pivot` (3,).

    pivot defaults to the curve's start C(0): a part turns about the joint it grows from."""
    op = "rotate"
    check_gc(op, gc)
    axis = check_array(op, gc, "axis", axis, (3,))
    if np.linalg.norm(axis) < 1e-12:
        raise EditError("must be a nonzero vector", op=op, gc=gc.name, field="axis", value=axis)
    deg = check_number(op, gc, "degrees", degrees)
    p = gc.curve.points[0] if pivot is None else check_array(op, gc, "pivot", pivot, (3,))
    R = Rotation.from_rotvec(axis / np.linalg.norm(axis) * math.radians(deg)).as_matrix()
    return gc.transformed(R, p - R @ p)


def translate(gc: GeneralizedCylinder, offset) -> GeneralizedCylinder:
    """Move the GC by `offset` (3,)."""
    op = "translate"
    check_gc(op, gc)
    return gc.transformed(np.eye(3), check_array(op, gc, "offset", offset, (3,)))


def stretch_map(gc: GeneralizedCylinder, t0: float, t1: float, factor: float):
    """The parameter map of `stretch`: nodes (tn, arc) of the new GC's `reparam` and its length.

    With alpha the GC's map from the network's t to normalised arc length (the identity unless
    an earlier stretch set one), the range [t0, t1] covers old arc lengths [a, b] = alpha(t0) L,
    alpha(t1) L. Old arc length sigma becomes sigma' = sigma before a, a + factor (sigma - a)
    inside, sigma + (factor - 1)(b - a) after, so L' = L + (factor - 1)(b - a) and the new map
    is t -> sigma'(alpha(t) L) / L'. Both maps are piecewise linear and the breaks of the second
    sit at t0 and t1, so the composition is exact on the nodes (old nodes plus t0, t1).
    Returns (tn (M,), arc (M,), L') as float64, tn and arc increasing from 0 to 1."""
    L = gc.length
    if gc.reparam is None:
        tn_old = np.array([0.0, 1.0])
    else:
        tn_old = gc.reparam[0]
    keep = (np.abs(tn_old - t0) > KEY_TOL) & (np.abs(tn_old - t1) > KEY_TOL)
    tn = np.unique(np.concatenate([tn_old[keep], [t0, t1]]))
    alpha = gc.arc_of_t(torch.as_tensor(tn, dtype=torch.float64)).numpy()
    a, b = (float(gc.arc_of_t(torch.tensor([x], dtype=torch.float64))[0]) * L for x in (t0, t1))
    L_new = L + (factor - 1.0) * (b - a)
    sig = alpha * L
    sig = np.where(sig <= a, sig, np.where(sig <= b, a + factor * (sig - a),
                                           sig + (factor - 1.0) * (b - a)))
    arc = np.clip(sig / L_new, 0.0, 1.0)
    arc[0], arc[-1] = 0.0, 1.0
    return tn, arc, L_new


def stretch(gc: GeneralizedCylinder, t0: float, t1: float, factor: float,
            samples: int = 65) -> GeneralizedCylinder:
    """Make the piece of the GC over network parameters [t0, t1] `factor` times longer; the rest
    keeps its length, and the neural features of [t0, t1] spread over the longer piece.

    t0, t1 are the network's t (what the keys and u = 2t - 1 refer to; normalised arc length
    unless an earlier stretch reparameterised the GC). Construction:
    - Curve: the old curve with its piece over [t0, t1] scaled by `factor` about the piece's
      start and the piece after it translated so it stays attached. Tangent directions are
      unchanged everywhere (the curve stays C1; curvature inside the range divides by
      `factor`); for a straight piece this is "extend along the tangent". A straight curve
      stays the same kind (control points evenly spaced on the longer segment) and
      t0 = 0, t1 = 1 scales every control point about C(0): both exact. A curved piece is not
      a single Bezier any more, so the result is a SplineCurve through `samples` points of the
      exact map plus both joints, uniform in arc length (arc lengths within ~1e-4 relative).
    - Parameter: keys stay at their t; the GC's `reparam` (see `stretch_map`) sends [t0, t1]
      onto the `factor`-times longer arc range, so radii, twists and the network's features
      u = 2t - 1 of that range are carried along the stretched piece, the rest keep their
      place. A uniform stretch (0, 1) leaves the map as it was.
    """
    op = "stretch"
    check_gc(op, gc)
    t0, t1 = check_range(op, gc, t0, t1)
    f = check_number(op, gc, "factor", factor, positive=True)
    pts = gc.curve.points
    L = gc.length
    if t0 == 0.0 and t1 == 1.0:  # uniform: an exact affine map of the control points
        curve = gc.curve.with_points(pts[0] + f * (pts - pts[0]))
        return rebuild(op, gc, curve=curve, up=carry_up(gc, curve))
    tn, arc, L_new = stretch_map(gc, t0, t1, f)
    s0, s1 = (float(gc.arc_of_t(torch.tensor([x], dtype=torch.float64))[0]) for x in (t0, t1))
    ends = curve_points_at(gc, [0.0, s0, s1, 1.0])
    if np.linalg.norm(ends[3] - ends[0]) >= L * (1.0 - 1e-7):  # straight
        d = (ends[3] - ends[0]) / np.linalg.norm(ends[3] - ends[0])
        curve = gc.curve.with_points(ends[0] + np.linspace(0.0, L_new, len(pts))[:, None] * d)
    else:
        a, b = s0 * L, s1 * L
        joints = np.array([a, a + f * (b - a)])
        grid = np.linspace(0.0, L_new, max(int(samples), 5))
        near = np.abs(grid[:, None] - joints[None]).min(1) < 0.25 * (grid[1] - grid[0])
        sig_new = np.sort(np.concatenate([grid[~near], joints]))
        # invert the arc-length map, evaluate, apply the piecewise map to the points
        sig_old = np.where(sig_new <= a, sig_new,
                           np.where(sig_new <= joints[1], a + (sig_new - a) / f,
                                    sig_new - (f - 1.0) * (b - a)))
        C = curve_points_at(gc, np.clip(sig_old / L, 0.0, 1.0))
        inside = (sig_new > a) & (sig_new <= joints[1])
        after = sig_new > joints[1]
        X = C + inside[:, None] * (f - 1.0) * (C - ends[1]) \
            + after[:, None] * (f - 1.0) * (ends[2] - ends[1])
        curve = SplineCurve(X)
    return rebuild(op, gc, curve=curve, up=carry_up(gc, curve), reparam=(tn, arc))


def scale_radii(gc: GeneralizedCylinder, t: float | None, factor,
                falloff: float | None = None) -> GeneralizedCylinder:
    """Scale the radii at the key at t by `factor` (one number, or [f_y, f_z]).

    A key is inserted at t if none is there; no other key changes, so the change ramps
    linearly to the neighbouring keys. `falloff` = w pins the profile with keys at t - w and
    t + w (inside (0, 1)), confining the change to (t - w, t + w). t = None scales every key
    (the whole GC's cross-sections, areas by f_y f_z)."""
    op = "scale_radii"
    check_gc(op, gc)
    f = check_factor(op, gc, "factor", factor)

    def scaled(k: Key) -> Key:
        return Key(k.t, (k.radii[0] * f[0], k.radii[1] * f[1]), k.twist)

    return rebuild(op, gc, keys=_edit_keys(op, gc, t, falloff, scaled, "scales"))


def twist(gc: GeneralizedCylinder, t: float | None, degrees: float,
          falloff: float | None = None) -> GeneralizedCylinder:
    """Add `degrees` of twist (about the tangent) at the key at t.

    Same key handling as `scale_radii`: a key is inserted at t if needed, neighbours stay, and
    `falloff` pins the profile at t -/+ w. t = None adds the twist to every key (a roll of the
    whole cross-section field; 360 degrees gives back the same GC)."""
    op = "twist"
    check_gc(op, gc)
    deg = check_number(op, gc, "degrees", degrees)

    def twisted(k: Key) -> Key:
        return Key(k.t, k.radii, k.twist + deg)

    return rebuild(op, gc, keys=_edit_keys(op, gc, t, falloff, twisted, "twists"))


def twist_ramp(gc: GeneralizedCylinder, t0: float, t1: float,
               degrees: float) -> GeneralizedCylinder:
    """Twist growing linearly from 0 at t0 to `degrees` at t1 and staying `degrees` after t1
    (a twisted bar: t0 = 0, t1 = 1). Keys are inserted at t0 and t1 with the interpolated
    profile, so the added twist is exactly this ramp."""
    op = "twist_ramp"
    check_gc(op, gc)
    t0, t1 = check_range(op, gc, t0, t1, fix="give t0 < t1 (or use 'twist' at one key)")
    deg = check_number(op, gc, "degrees", degrees)
    keys = [Key(k.t, k.radii, k.twist + deg * min(max((k.t - t0) / (t1 - t0), 0.0), 1.0))
            for k in with_keys_at(gc, [t0, t1])]
    return rebuild(op, gc, keys=keys)


def local_motion(old: GeneralizedCylinder, new: GeneralizedCylinder,
                 point) -> tuple[np.ndarray, np.ndarray]:
    """The rigid motion (R (3, 3), t (3,)) an edit old -> new applies near `point` (3,).

    The point keeps its relative coordinates (so it lands on new.to_world(old.to_relative(p)))
    and turns with the frame (T, N, B) at its closest curve point. A part attached there (a
    head on a neck, a leg on a stretched torso) follows an edit by this motion."""
    p = np.asarray(point, dtype=np.float64).reshape(1, 3)
    rel = old.to_relative(p)
    q = new.to_world(rel)[0]
    t = torch.tensor([(min(max(float(rel[0, 0]), -1.0), 1.0) + 1.0) / 2.0], dtype=torch.float64)

    def frame(g):
        s = g.arc.s_of_t(g.arc_of_t(t))
        return torch.cat(g.frame(s, t)[1:]).numpy()  # rows T, N, B

    R = frame(new).T @ frame(old)
    return R, q - R @ p[0]


# ---- programs --------------------------------------------------------------------------------
OPS: dict[str, Callable[..., GeneralizedCylinder]] = {
    "move": move_points, "bend": move_points, "rigid": rigid, "rotate": rotate,
    "translate": translate, "stretch": stretch, "scale": scale_radii, "twist": twist,
    "twist_ramp": twist_ramp,
}


def apply(gc: GeneralizedCylinder, op: str, **params) -> GeneralizedCylinder:
    """Apply the op named `op` (a key of OPS) with keyword `params`, as an edit program does."""
    if op not in OPS:
        raise EditError(f"unknown op; use one of {sorted(OPS)}", gc=_name(gc), field="op",
                        value=op)
    fn = OPS[op]
    try:
        inspect.signature(fn).bind(gc, **params)
    except TypeError as e:
        names = [p for p in inspect.signature(fn).parameters if p != "gc"]
        raise EditError(f"bad parameters {sorted(params)} ({e}); it takes {names}", op=op,
                        gc=_name(gc)) from None
    return fn(gc, **params)


def compose(gc: GeneralizedCylinder, ops: Iterable) -> GeneralizedCylinder:
    """Apply edits in order. Each entry is a callable GC -> GC, a mapping {op: name, ...params}
    or a pair (name, params)."""
    for entry in ops:
        if callable(entry):
            gc = entry(gc)
        elif isinstance(entry, dict):
            params = dict(entry)
            if "op" not in params:
                raise EditError(f"an op entry needs an 'op' name, got {entry!r}", gc=_name(gc))
            gc = apply(gc, params.pop("op"), **params)
        else:
            try:
                name, params = entry
                params = dict(params)
            except (TypeError, ValueError):
                raise EditError(f"an op entry must be a callable, a mapping {{op: name, ...}} "
                                f"or a pair (name, params), got {entry!r}", gc=_name(gc)) from None
            gc = apply(gc, name, **params)
    return gc
