import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.geometry import GeneralizedCylinder, GeometryError
from ngc_gen.geometry.arrays import GeometryShapeError
from ngc_gen.geometry.closest_check import closest_point_excess

from .conftest import inside_rel_samples, random_gc_dict


@pytest.mark.parametrize("kind", ["bezier", "spline"])
def test_round_trip_random_gcs(rng, kind):
    for trial in range(12):
        gc = GeneralizedCylinder.from_dict(random_gc_dict(rng, degree=trial % 5 + 1, kind=kind))
        rel = inside_rel_samples(rng, 3000)
        q = gc.to_world(rel)
        rel2 = gc.to_relative(q)
        assert np.abs(gc.to_world(rel2) - q).max() < 1e-5, gc
        assert np.abs(rel2 - rel).max() < 1e-5, gc


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_round_trip_dtypes_and_types(rng, dtype):
    gc = GeneralizedCylinder.from_dict(random_gc_dict(rng, degree=3))
    q = gc.to_world(inside_rel_samples(rng, 2000)).astype(dtype)
    rel = gc.to_relative(q)
    assert isinstance(rel, np.ndarray) and rel.dtype == dtype
    assert np.abs(gc.to_world(rel) - q).max() < 1e-5
    qt = torch.from_numpy(q)
    relt = gc.to_relative(qt)
    assert isinstance(relt, torch.Tensor) and relt.dtype == qt.dtype
    assert torch.allclose(relt, torch.from_numpy(rel), atol=1e-6)
    inside = gc.contains(qt)
    assert isinstance(inside, torch.Tensor) and inside.dtype == torch.bool


def test_rigid_motion_leaves_relative_coordinates_unchanged(rng):
    gc = GeneralizedCylinder.from_dict(random_gc_dict(rng, degree=4))
    q = gc.to_world(inside_rel_samples(rng, 3000))
    R = Rotation.random(random_state=7).as_matrix()
    t = np.array([0.3, -0.2, 0.5])
    moved = gc.transformed(R, t)
    np.testing.assert_allclose(moved.to_relative(q @ R.T + t), gc.to_relative(q), atol=1e-8)


def test_straight_unit_gc_is_affine():
    L = 1.6
    gc = GeneralizedCylinder.from_dict({
        "name": "bar", "curve": {"type": "bezier", "points": [[-0.8, 0, 0], [0.8, 0, 0]]},
        "up": [0, 0, 1], "keys": [{"t": 0, "radii": [1, 1]}], "caps": [1, 1]})
    rng = np.random.default_rng(0)
    rel = inside_rel_samples(rng, 2000)
    rel = rel[np.abs(rel[:, 0]) <= 1]
    w = gc.to_world(rel)
    # world = A rel + c with x = -0.8 + (u+1)/2 L, y = a (frame y from up=z ... rotated: y = z x x)
    A, *_ = np.linalg.lstsq(np.c_[rel, np.ones(len(rel))], w, rcond=None)
    np.testing.assert_allclose(np.c_[rel, np.ones(len(rel))] @ A, w, atol=1e-9)
    np.testing.assert_allclose(A[0], [L / 2, 0, 0], atol=1e-9)
    np.testing.assert_allclose(A[3], [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(np.abs(A[1:3]), [[0, 0, 1], [0, 1, 0]], atol=1e-9)


def test_contains_matches_analytic_capsule():
    ry, rz, l0, l1 = 0.2, 0.1, 0.15, 0.3
    gc = GeneralizedCylinder.from_dict({
        "name": "c", "curve": {"type": "bezier", "points": [[-0.5, 0, 0], [0.0, 0, 0], [0.5, 0, 0]]},
        "up": [0, 1, 0], "keys": [{"t": 0, "radii": [ry, rz]}], "caps": [l0, l1]})
    rng = np.random.default_rng(3)
    q = rng.uniform([-1, -0.3, -0.3], [1, 0.3, 0.3], (100_000, 3))
    x, y, z = q.T
    e = np.where(x < -0.5, (x + 0.5) / l0, np.where(x > 0.5, (x - 0.5) / l1, 0.0))
    analytic = e ** 2 + (y / ry) ** 2 + (z / rz) ** 2 <= 1
    ours = gc.contains(q)
    assert analytic.sum() > 5000
    assert np.mean(ours == analytic) > 0.9999  # disagreements only within rounding of the boundary


def test_bounds_enclose_the_gc(rng):
    for _ in range(5):
        gc = GeneralizedCylinder.from_dict(random_gc_dict(rng))
        lo, hi = gc.bounds()
        rel = inside_rel_samples(rng, 5000)
        rel[:, 1:] /= np.linalg.norm(rel[:, 1:], axis=1, keepdims=True).clip(1, None)
        w = gc.to_world(rel)
        assert np.all(w >= lo) and np.all(w <= hi)


def test_twist_360_equals_no_twist(rng):
    d = random_gc_dict(rng, degree=3)
    d["keys"] = [{"t": 0, "radii": [0.05, 0.03], "twist": 0}, {"t": 1, "radii": [0.05, 0.03], "twist": 0}]
    a = GeneralizedCylinder.from_dict(d)
    d["keys"][1]["twist"] = 360
    b = GeneralizedCylinder.from_dict(d)
    mid = np.array([[0.0, 0.6, 0.3]])  # half way the 360-degree twist has turned 180 degrees
    assert np.linalg.norm(b.to_world(mid) - a.to_world(mid)) > 0.02
    ends = np.array([[1.0, 0.5, 0.5], [-1.0, 0.5, 0.5], [1.5, 0.3, -0.2], [-1.5, 0.1, 0.4]])
    np.testing.assert_allclose(b.to_world(ends), a.to_world(ends), atol=1e-9)


def test_dict_round_trip(rng):
    d = random_gc_dict(rng, kind="spline")
    gc = GeneralizedCylinder.from_dict(d)
    gc2 = GeneralizedCylinder.from_dict(gc.to_dict())
    q = gc.to_world(inside_rel_samples(rng, 500))
    np.testing.assert_array_equal(gc2.to_relative(q), gc.to_relative(q))


def test_chunking_does_not_change_results(rng):
    d = random_gc_dict(rng, degree=2)
    q = rng.uniform(-1, 1, (5000, 3))
    big = GeneralizedCylinder.from_dict(d).to_relative(q)
    small = GeneralizedCylinder.from_dict(d, chunk=97).to_relative(q)
    np.testing.assert_array_equal(big, small)


BASE = {"name": "leg", "curve": {"type": "bezier", "points": [[0, 0, 0], [1, 0, 0]]},
        "up": [0, 0, 1], "keys": [{"t": 0, "radii": [0.1, 0.1]}], "caps": [0.1, 0.1]}


@pytest.mark.parametrize("change, field, words", [
    ({"curve": {"type": "bezier", "points": [[0, 0, 0], [0, 0, 0]]}}, "curve.points", "zero length"),
    ({"curve": {"type": "bezier", "points": [[0, 0, 0]]}}, "curve.points", "at least 2"),
    ({"curve": {"type": "spline", "points": [[0, 0, 0], [0, 0, 0], [1, 0, 0]]}}, "curve.points", "coincide"),
    ({"curve": {"type": "nurbs", "points": [[0, 0, 0], [1, 0, 0]]}}, "curve.type", "unknown curve type"),
    ({"curve": {"type": "bezier", "points": [[0, 0, float("nan")], [1, 0, 0]]}}, "curve.points", "NaN"),
    ({"keys": [{"t": 0, "radii": [0.0, 0.1]}]}, "keys[0].radii", "positive"),
    ({"keys": [{"t": 1.5, "radii": [0.1, 0.1]}]}, "keys[0].t", "[0, 1]"),
    ({"keys": []}, "keys", "at least one key"),
    ({"caps": [0.0, 0.1]}, "caps", "positive"),
    ({"up": [1, 0, 0]}, "up", "parallel"),
    ({"radius": 3}, None, "unknown fields"),
])
def test_bad_gc_gives_clear_error(change, field, words):
    d = {**BASE, **change}
    with pytest.raises(GeometryError) as e:
        GeneralizedCylinder.from_dict(d)
    assert e.value.gc_name == "leg" and e.value.field == field
    assert words in str(e.value) and "leg" in str(e.value)


def test_bad_point_shape():
    gc = GeneralizedCylinder.from_dict(BASE)
    with pytest.raises(GeometryShapeError):
        gc.to_relative(np.zeros((10, 2)))


def test_reparam_round_trip_and_serialisation(rng):
    d = random_gc_dict(rng, degree=3)
    d["reparam"] = {"t": [0.0, 0.3, 0.5, 1.0], "arc": [0.0, 0.2, 0.6, 1.0]}
    gc = GeneralizedCylinder.from_dict(d)
    rel = inside_rel_samples(rng, 2000)
    q = gc.to_world(rel)
    np.testing.assert_allclose(gc.to_relative(q), rel, atol=1e-9)
    # network t = 0.5 (u = 0) sits at 60% of the arc length
    plain = GeneralizedCylinder.from_dict({k: v for k, v in d.items() if k != "reparam"})
    np.testing.assert_allclose(gc.to_world(np.array([[0.0, 0, 0]])),
                               plain.to_world(np.array([[0.2, 0, 0]])), atol=1e-9)
    again = GeneralizedCylinder.from_dict(gc.to_dict())
    np.testing.assert_array_equal(again.to_relative(q), gc.to_relative(q))
    d["reparam"] = {"t": [0.0, 0.6, 0.5, 1.0], "arc": [0.0, 0.2, 0.6, 1.0]}
    with pytest.raises(GeometryError, match="reparam"):
        GeneralizedCylinder.from_dict(d)


# a U turn and a spiral-like bend; radii x 1.2 stay inside the radius of curvature (0.375,
# 0.281) and away from the other parts of the curve
CURVED = [([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], 0.3),
          ([[0, 0, 0], [1.5, 0, 0], [1.5, 1.2, 0], [0.0, 1.2, 0.0], [0, 0.3, 0.3]], 0.15)]


@pytest.mark.parametrize("points, r", CURVED)
def test_strongly_curved_gc_finds_the_nearest_foot_point(rng, points, r):
    """Inside and just outside a tight bend the foot point is the nearest curve point (the
    vertex descent and the seed must not stop at another local minimum)."""
    gc = GeneralizedCylinder.from_dict({"name": "bend", "curve": {"type": "bezier",
                                        "points": points}, "keys": [{"t": 0, "radii": [r, r]}]})
    rel = inside_rel_samples(rng, 4_000)
    rel = rel[np.abs(rel[:, 0]) < 1] * [1, 1.2, 1.2]
    excess = closest_point_excess(gc, gc.to_world(rel))
    assert excess.max() <= 1e-9 and excess.min() >= -1e-9


@pytest.mark.parametrize("points, r", CURVED)
def test_convex_radius_makes_the_window_convex(rng, points, r):
    """Within `convex[c]` of coarse vertex c, |C(t) - q|^2 is convex over the arc between c's
    coarse neighbours (what lets the kernel descend instead of scanning the window)."""
    gc = GeneralizedCylinder.from_dict({"name": "bend", "curve": {"type": "bezier",
                                        "points": points}, "keys": [{"t": 0, "radii": [r, r]}]})
    T = gc.tables
    K, co = gc.segments, T.coarse
    assert np.all(T.convex > 0)
    for c in range(len(co)):
        a, b = co[max(c - 1, 0)], co[min(c + 1, len(co) - 1)]
        t = torch.linspace(a / K, b / K, 401, dtype=torch.float64)
        C, d1, d2 = (x.numpy() for x in gc.curve.evaluate(gc.arc.s_of_t(t)))
        n2 = (d1 * d1).sum(1, keepdims=True)
        Ctt = (d2 - (d2 * d1).sum(1, keepdims=True) * d1 / n2) / n2  # kappa N
        d = rng.normal(size=(200, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        q = T.poly_x[co[c]] + T.convex[c] * rng.uniform(0.9, 1.0, (200, 1)) * d
        ftt = 1 + ((C[None] - q[:, None]) * Ctt[None]).sum(-1)  # f'' in arc length
        assert np.all(ftt > 0)


def test_centre_line_runs_along_the_curve_at_equal_arc_length(rng):
    gc = GeneralizedCylinder.from_dict(random_gc_dict(rng, degree=3))
    line = gc.centre_line(33)
    assert line.shape == (33, 3) and line.dtype == np.float64
    np.testing.assert_allclose(line[[0, -1]], np.asarray(gc.curve.points)[[0, -1]], atol=1e-9)
    steps = np.linalg.norm(np.diff(line, axis=0), axis=1)
    assert steps.std() < 0.02 * steps.mean()  # equal normalised arc length
    assert abs(steps.sum() - gc.length) < 0.01 * gc.length


def test_mean_radius_averages_each_keys_geometric_mean_radius():
    gc = GeneralizedCylinder.from_dict({
        "name": "bar", "curve": {"type": "bezier", "points": [[-0.8, 0, 0], [0.8, 0, 0]]},
        "keys": [{"t": 0, "radii": [1, 4]}, {"t": 0.5, "radii": [0.5, 0.5]},
                 {"t": 1, "radii": [0.25, 1]}]})
    assert gc.mean_radius() == pytest.approx((2.0 + 0.5 + 0.5) / 3)
