"""Where a picture's camera stands: the mesh's up axis (given or detected), the view direction
relative to it, the direction that shows an edit's motion, and the distance that frames a set
of points in a perspective view. Pure numpy functions; `render.render_grid` uses them.

Directions are unit (3,) float64 vectors in the mesh's frame (normalisation is a similarity
without rotation, so a mesh file's up is also its normalised frame's up).
"""
from __future__ import annotations

import math

import numpy as np

#: pyvista's (VTK's) default vertical view angle, degrees; render_grid sets it explicitly.
VIEW_ANGLE = 30.0
#: The side view: azimuth from straight across the shape's long side toward its +long end, and
#: elevation above the horizon, degrees. With z up and x the long side this is the direction
#: (1, -1.6, 0.9) the pictures always used.
AZIMUTH, ELEVATION = 32.0, 25.5
#: The lowest elevation an edit picture goes down to in order to look across the motion.
MIN_ELEVATION = 10.0
#: How much more of the motion (a fraction of its squared length) an edit picture may hide in
#: order to look from the moved part's side rather than across the rest of the shape.
SIDE_TOLERANCE = 1e-2

_AXES = {"x": 0, "y": 1, "z": 2}


def up_vector(spec) -> np.ndarray | None:
    """The up vector a setting names: 'x' | 'y' | 'z' with an optional sign ('-y', '+z'), or
    three numbers [x, y, z]; None for 'auto' (detect it: `detect_up`). ValueError otherwise."""
    if isinstance(spec, str):
        s = spec.strip().lower()
        if s == "auto":
            return None
        sign = -1.0 if s.startswith("-") else 1.0
        axis = s.lstrip("+-")
        if axis in _AXES and len(s) - len(axis) <= 1:
            v = np.zeros(3)
            v[_AXES[axis]] = sign
            return v
    else:
        try:
            v = np.asarray(list(spec), dtype=np.float64)
        except (TypeError, ValueError):
            v = None
        if v is not None and v.shape == (3,) and np.isfinite(v).all() and np.linalg.norm(v) > 0:
            return v / np.linalg.norm(v)
    raise ValueError(f"up must be auto, x, y, z, -x, -y, -z or [x, y, z] (not zero), got "
                     f"{spec!r}; set it as viz.up=<value> (conf/viz/default.yaml)")


def frame_up(spec, frame: dict | None):
    """The `viz.up` a picture uses: a given axis as it is; for 'auto', the up of the body frame
    the shapes were written in (an annotation's or a model's `frame`), when one is recorded;
    else 'auto' (detected from the meshes)."""
    if frame is not None and isinstance(spec, str) and spec.strip().lower() == "auto":
        return [float(x) for x in frame["up"]]
    return spec


def _hull_area_2d(points: np.ndarray) -> float:
    from scipy.spatial import ConvexHull, QhullError

    if len(points) < 3:
        return 0.0
    try:
        return float(ConvexHull(points).volume)  # a 2-D hull's volume is its area
    except QhullError:  # collinear
        return 0.0


def support_areas(vertices: np.ndarray, eps: float = 0.03) -> np.ndarray:
    """(3, 2) float: for axis k and side (min, max), the area of the convex hull's vertices
    within eps * (longest bounding-box side) of that bounding-box face, projected on the face,
    over the face's area: how much the shape would stand on that face (feet, a flat bottom)."""
    from scipy.spatial import ConvexHull, QhullError

    V = np.asarray(vertices, dtype=np.float64)
    lo, hi = V.min(0), V.max(0)
    ext = hi - lo
    out = np.zeros((3, 2))
    try:
        H = V[ConvexHull(V - (lo + hi) / 2).vertices]
    except QhullError:  # flat or degenerate: no solid to stand
        return out
    band = eps * float(ext.max())
    for k in range(3):
        o = [a for a in range(3) if a != k]
        face = float(ext[o[0]] * ext[o[1]])
        if face <= 0:
            continue
        out[k, 0] = _hull_area_2d(H[H[:, k] <= lo[k] + band][:, o]) / face
        out[k, 1] = _hull_area_2d(H[H[:, k] >= hi[k] - band][:, o]) / face
    return out


def detect_up(vertices: np.ndarray, min_base: float = 0.15, flat: float = 0.5) -> np.ndarray:
    """The up axis of a mesh, by a deterministic rule over its axis-aligned bounding box:

    1. A base: for each axis, the support of its two faces (`support_areas`: the hull's
       footprint within 3% of the longest side of the face, over the face's area). A shape
       standing on feet or a flat bottom has a large footprint below and a small one above;
       equal footprints (a rod's two ends, a plate's two sides, a creature's left and right)
       say nothing. If the largest difference (bottom minus top) is at least `min_base` and at
       least twice any other axis's, up points from that bottom face to its opposite.
    2. Else a flat shape: if the smallest bounding-box side is at most `flat` times the middle
       one, up is + that axis (a plate or an airplane seen from above; the sign is a guess).
    3. Else +z (the project's convention; the creatures are z-up).

    Measured by bench/up_axis.py: pyvista's ant -> +y (rule 1), airplane -> +z (rule 2), 64
    creatures -> +z (rule 1); each also when turned to x-, y- or -z-up, except that
    an upside-down airplane is still called +z. Shapes without a base, neither flat nor z-up (a
    pole along x, a cube) get +z, and boxy shapes whose flat sides count as bases too (a
    cupboard) fall through to rules 2-3: set `viz.up` for those.

    vertices: (V, 3) float. Returns a unit (3,) float64 axis vector."""
    V = np.asarray(vertices, dtype=np.float64)
    up = np.zeros(3)
    s = support_areas(V)
    score = s[:, 0] - s[:, 1]  # > 0: stands on its min face, up is +axis
    k = int(np.argmax(np.abs(score)))
    others = np.delete(np.abs(score), k)
    if abs(score[k]) >= min_base and abs(score[k]) >= 2 * others.max():
        up[k] = math.copysign(1.0, score[k])
        return up
    ext = V.max(0) - V.min(0)
    order = np.argsort(ext, kind="stable")
    if ext[order[0]] <= flat * ext[order[1]]:
        up[order[0]] = 1.0
        return up
    up[2] = 1.0
    return up


def resolve_up(spec, meshes) -> np.ndarray:
    """The up vector of a set of meshes: `spec` if it names one (`up_vector`), else for 'auto'
    the axis `detect_up` finds for most of them (a tie: the first mesh's). meshes: trimesh
    meshes or (V, 3) arrays; None and empty ones are skipped (none left: +z)."""
    v = up_vector(spec)
    if v is not None:
        return v
    votes: list[tuple] = []
    for m in meshes:
        V = np.asarray(getattr(m, "vertices", m), dtype=np.float64)
        if V.ndim == 2 and len(V) >= 4:
            votes.append(tuple(detect_up(V)))
    if not votes:
        return np.array([0.0, 0.0, 1.0])
    return np.asarray(max(votes, key=votes.count), dtype=np.float64)  # first of the most common


def horizontal_axes(up) -> tuple[np.ndarray, np.ndarray]:
    """Two orthonormal directions perpendicular to `up`: the world axes other than the one
    closest to up (in x, y, z order), made perpendicular to up."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    out = []
    for k in np.delete(np.arange(3), int(np.argmax(np.abs(u)))):
        e = np.eye(3)[k] - u[k] * u
        for f in out:
            e = e - (e @ f) * f
        out.append(e / np.linalg.norm(e))
    return out[0], out[1]


def _direction(horizontal: np.ndarray, up: np.ndarray, elevation: float) -> np.ndarray:
    e = math.radians(elevation)
    d = math.cos(e) * horizontal + math.sin(e) * up
    return d / np.linalg.norm(d)


def side_view(points: np.ndarray, up, azimuth: float = AZIMUTH,
              elevation: float = ELEVATION) -> np.ndarray:
    """Direction from the shape toward the camera: across the shape's longer horizontal side
    (of the two `horizontal_axes`, by the points' extent; a tie takes the first), turned by
    `azimuth` degrees toward its + end, `elevation` degrees above the horizon.

    points: (N, 3) float. Returns a unit (3,) vector."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    P = np.asarray(points, dtype=np.float64)
    h1, h2 = horizontal_axes(u)
    ext = [float(np.ptp(P @ h)) if len(P) else 0.0 for h in (h1, h2)]
    long = h1 if ext[0] >= ext[1] else h2
    across = np.cross(u, long)
    a = math.radians(azimuth)
    return _direction(math.sin(a) * long - math.cos(a) * across, u, elevation)


def least_motion_view(displacements: np.ndarray, up, reference: np.ndarray,
                      min_elevation: float = MIN_ELEVATION, toward=None) -> np.ndarray:
    """The camera direction that shows a motion best: the one along which the displacements
    move least, so their motion lies in the image plane.

    With M = sum of d d^T over the displacements d, minimise v^T M v over directions v between
    `min_elevation` and the reference's elevation above the horizon (grid of 0.1 degree in
    azimuth, 0.25 degree in elevation). Of the directions within 1e-4 trace(M) of the least,
    keep those on the side `toward` points to (v . toward > 0: the camera stands on the moved
    part's side, so the rest of the shape does not hide it), if any of them is within
    SIDE_TOLERANCE trace(M) of the least; then take the highest, then the one nearest
    `reference`. A motion within the reachable band is then perpendicular to v (to grid
    precision); no motion returns `reference`.

    displacements: (K, 3) float; toward: (3,) float or None. Returns a unit (3,) vector."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    ref = np.asarray(reference, dtype=np.float64)
    ref = ref / np.linalg.norm(ref)
    D = np.asarray(displacements, dtype=np.float64).reshape(-1, 3)
    M = D.T @ D
    tr = float(np.trace(M))
    if not tr > 0:
        return ref
    top = math.degrees(math.asin(float(np.clip(ref @ u, -1, 1))))
    top = max(top, min_elevation)
    elev = np.radians(np.arange(top, min_elevation - 1e-9, -0.25))
    az = np.radians(np.arange(0.0, 360.0, 0.1))
    h1, h2 = horizontal_axes(u)
    H = np.cos(az)[:, None] * h1 + np.sin(az)[:, None] * h2                # (A, 3)
    V = (np.cos(elev)[:, None, None] * H[None] + np.sin(elev)[:, None, None] * u)  # (E, A, 3)
    f = np.einsum("eai,ij,eaj->ea", V, M, V)
    ok = f <= f.min() + 1e-4 * tr
    if toward is not None and np.linalg.norm(toward) > 0:
        facing = V @ np.asarray(toward, dtype=np.float64) > 0
        if facing.any() and f[facing].min() <= f.min() + SIDE_TOLERANCE * tr:
            ok = facing & (f <= f[facing].min() + 1e-4 * tr)
    e = int(np.argmax(ok.any(1)))  # elevations run from the top down
    cand = np.flatnonzero(ok[e])
    best = cand[int(np.argmax(V[e, cand] @ ref))]
    return V[e, best] / np.linalg.norm(V[e, best])


def _curve_motion(before, after, n: int = 33) -> tuple[np.ndarray, np.ndarray]:
    """(points, displacements), both (K, 3): the curve points of GCs in `before` (n per curve
    at equal normalised arc length, paired with `after` by name) and how far each moved."""
    by_name = {g.name: g for g in after}
    pairs = [(g.centre_line(n), by_name[g.name].centre_line(n))
             for g in before if g.name in by_name]
    if not pairs:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return (np.concatenate([p for p, _ in pairs]),
            np.concatenate([q - p for p, q in pairs]))


def curve_displacements(before, after, n: int = 33) -> np.ndarray:
    """(K, 3) float: how the curve points of GCs moved from `before` to `after` (GC lists,
    paired by name; n points per curve at equal normalised arc length). GCs that did not move
    give zero rows."""
    return _curve_motion(before, after, n)[1]


def moved_side(points: np.ndarray, before, after, up, n: int = 33) -> np.ndarray | None:
    """The horizontal direction from the centre of `points` (their bounding box) to where the
    GCs moved: the curve points before and after, weighted by how far each moved, projected
    off `up`. None when nothing moved or the motion is centred. (3,) float64."""
    P, D = _curve_motion(before, after, n)
    w = np.linalg.norm(D, axis=1)
    if not len(w) or not w.sum() > 0:
        return None
    Q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    centre = (Q.min(0) + Q.max(0)) / 2 if len(Q) else np.zeros(3)
    at = ((P + D / 2) * w[:, None]).sum(0) / w.sum()
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    side = (at - centre) - ((at - centre) @ u) * u
    return side if np.linalg.norm(side) > 1e-9 else None


def camera_distance(points: np.ndarray, center: np.ndarray, direction: np.ndarray, up,
                    aspect: float, view_angle: float = VIEW_ANGLE,
                    fill: tuple[float, float] = (0.9, 0.9)) -> float:
    """Distance from `center` along `direction` at which a perspective camera (vertical view
    angle `view_angle` degrees, width/height `aspect`, looking at `center`, `up` as its up)
    sees every point within the central fraction `fill` = (width, height) of its image.

    A point q (offset p = q - center) lies at depth D - p.d in front of the camera and at
    p.r, p.t across (r, t: the image's right and up). It is inside the fraction f of a half
    angle a iff |p.r| <= (D - p.d) f tan(a_h) and |p.t| <= (D - p.d) f tan(a_v), so
    D = max over points of p.d + max(|p.r| / (f_w tan a_h), |p.t| / (f_h tan a_v)).

    points: (N, 3) float. Returns D > 0."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    t = np.asarray(up, dtype=np.float64) - (np.asarray(up, dtype=np.float64) @ d) * d
    if np.linalg.norm(t) < 1e-9:  # looking along up: any perpendicular will do
        t = horizontal_axes(d)[0]
    t = t / np.linalg.norm(t)
    r = np.cross(d, t)
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3) - np.asarray(center, np.float64)
    tan_v = math.tan(math.radians(view_angle) / 2)
    tan_h = tan_v * aspect
    if not len(P) or not np.abs(P).max() > 0:
        return 1.0
    need = P @ d + np.maximum(np.abs(P @ r) / (fill[0] * tan_h),
                              np.abs(P @ t) / (fill[1] * tan_v))
    return float(need.max()) + 1e-6 * float(np.linalg.norm(P, axis=1).max())


def edit_view(points: np.ndarray, gcs_before, gcs_after, up) -> np.ndarray:
    """The camera direction of an edit's before/after picture: `least_motion_view` of the GCs'
    curve displacements (`curve_displacements`), from the side the moved GCs are on
    (`moved_side`), the side view of `points` (before and after together) breaking ties.
    Looking across the motion shows it at its full length: a leg raised by handles turns in
    the plane the camera faces, not toward it. Unit (3,) vector."""
    return least_motion_view(curve_displacements(gcs_before, gcs_after), up,
                             side_view(points, up),
                             toward=moved_side(points, gcs_before, gcs_after, up))


def frame_points(points: np.ndarray, direction: np.ndarray, up, aspect: float,
                 view_angle: float = VIEW_ANGLE, fill: tuple[float, float] = (0.9, 0.9),
                 steps: int = 3) -> tuple[np.ndarray, float]:
    """(focal point, distance) of a camera looking along -`direction` that shows every point
    inside the central fraction `fill` of the image, the points centred: start at their
    bounding-box centre, then `steps` times move the focal point across the view by the middle
    of the points' projected extent (perspective makes the box centre project off-centre) and
    recompute `camera_distance` there, which keeps every point inside whatever the shift.

    points: (N, 3) float."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    if not len(P):
        return np.zeros(3), 1.0
    t = np.asarray(up, dtype=np.float64) - (np.asarray(up, dtype=np.float64) @ d) * d
    t = horizontal_axes(d)[0] if np.linalg.norm(t) < 1e-9 else t / np.linalg.norm(t)
    r = np.cross(d, t)
    c = (P.min(0) + P.max(0)) / 2
    D = camera_distance(P, c, d, t, aspect, view_angle, fill)
    for _ in range(steps):
        Q = P - (c + D * d)
        depth = -(Q @ d)
        x, y = (Q @ r) / depth, (Q @ t) / depth
        c = c + D * ((x.max() + x.min()) / 2 * r + (y.max() + y.min()) / 2 * t)
        D = camera_distance(P, c, d, t, aspect, view_angle, fill)
    return c, D
