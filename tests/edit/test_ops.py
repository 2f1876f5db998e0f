import functools
import math

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.edit import (EditError, apply, compose, local_motion, move_points, rigid, rotate,
                          scale_radii, stretch, stretch_map, translate, twist, twist_ramp)
from ngc_gen.geometry import BezierCurve, GeneralizedCylinder, SplineCurve


def make_gc(points, kind="bezier", keys=None, name="part"):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": kind, "points": points}, "up": [0, 0, 1],
        "keys": keys or [{"t": 0.0, "radii": [0.12, 0.08], "twist": 10.0},
                         {"t": 0.5, "radii": [0.10, 0.09], "twist": 40.0},
                         {"t": 1.0, "radii": [0.06, 0.05], "twist": -20.0}],
        "caps": [0.05, 0.04]})


@pytest.fixture
def curved():
    return make_gc([[0, 0, 0], [0.4, 0.3, 0.0], [0.8, -0.2, 0.1], [1.2, 0.1, 0.0]])


@pytest.fixture
def straight():
    return make_gc([[0, 0, 0], [0.3, 0, 0], [1.0, 0, 0]])


def rel_samples(n=400, seed=0):
    rng = np.random.default_rng(seed)
    rel = np.stack([rng.uniform(-2, 2, 4 * n), rng.uniform(-1, 1, 4 * n),
                    rng.uniform(-1, 1, 4 * n)], 1)
    return rel[GeneralizedCylinder.inside_relative(rel)][:n]


def t_of(gc, points):
    """Normalised arc length of curve points (N, 3) on gc."""
    return (gc.to_relative(np.asarray(points, np.float64))[:, 0] + 1) / 2


def same_shape(a, b, atol=1e-9):
    rel = rel_samples()
    return np.abs(a.to_world(rel) - b.to_world(rel)).max() < atol


# ---- identity edits --------------------------------------------------------------------------
def test_identity_edits_leave_the_gc_unchanged(curved):
    for edited in (move_points(curved, [0, 2], [0, 0, 0]), scale_radii(curved, None, 1.0),
                   scale_radii(curved, 0.3, 1.0), twist(curved, 0.7, 0.0),
                   twist(curved, None, 360.0), stretch(curved, 0.0, 1.0, 1.0),
                   rotate(curved, [1, 2, 3], 0.0), translate(curved, [0, 0, 0])):
        assert same_shape(curved, edited), edited
    assert curved.keys[1].twist == 40.0  # inputs are never changed


# ---- bend ------------------------------------------------------------------------------------
def test_move_points_moves_control_points_and_keeps_keys(curved):
    moved = move_points(curved, [-1, 2], [[0, 0.2, 0], [0, 0, 0.1]])
    np.testing.assert_allclose(moved.curve.points[3], curved.curve.points[3] + [0, 0.2, 0])
    np.testing.assert_allclose(moved.curve.points[2], curved.curve.points[2] + [0, 0, 0.1])
    assert moved.keys == curved.keys and isinstance(moved.curve, BezierCurve)
    # the start tangent did not change, so neither does up
    assert moved.name == curved.name and np.array_equal(moved.up, curved.up)
    end = moved.to_world(np.array([[1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(end[0], curved.curve.points[3] + [0, 0.2, 0], atol=1e-9)


def test_move_first_point_carries_up_with_the_start_tangent(straight):
    # turn the start tangent from +x to +z, parallel to the old up: up turns with it
    bent = move_points(straight, [0, 1], [[0, 0, -0.5], [-0.3, 0, 0]])
    s0 = torch.zeros(1, dtype=torch.float64)
    old = np.concatenate([v.numpy() for v in straight.frame(s0, s0)[1:]])
    new = np.concatenate([v.numpy() for v in bent.frame(s0, s0)[1:]])
    turn = Rotation.from_rotvec([0, -np.pi / 2, 0]).as_matrix()  # smallest rotation x -> z
    np.testing.assert_allclose(new, old @ turn.T, atol=1e-9)


def test_move_points_on_a_spline(curved):
    sp = make_gc([[0, 0, 0], [0.5, 0.2, 0], [1.0, 0, 0]], kind="spline")
    moved = move_points(sp, 1, [0, 0.1, 0])
    assert isinstance(moved.curve, SplineCurve)
    np.testing.assert_allclose(moved.to_world(np.array([[0.0, 0, 0]]))[0], [0.5, 0.3, 0],
                               atol=1e-3)


@pytest.mark.parametrize("indices, offsets, match", [
    ([4], [0, 0, 1], "unknown control point index"),
    ([-5], [0, 0, 1], "unknown control point index"),
    ([0, 0], [0, 0, 1], "twice"),
    ([0.5], [0, 0, 1], "ints"),
    ([0], [0, np.nan, 1], "NaN"),
    ([0, 1], [[0, 0, 1]] * 3, "shape"),
])
def test_move_points_rejects_bad_arguments(curved, indices, offsets, match):
    with pytest.raises(EditError, match=match) as e:
        move_points(curved, indices, offsets)
    assert "move_points" in str(e.value) and "'part'" in str(e.value)


# ---- rigid -----------------------------------------------------------------------------------
def test_rigid_motion_keeps_relative_coordinates(curved):
    R = Rotation.from_euler("xyz", [20, -35, 70], degrees=True).as_matrix()
    t = np.array([0.2, -0.1, 0.4])
    moved = rigid(curved, R, t)
    q = curved.to_world(rel_samples())
    np.testing.assert_allclose(moved.to_relative(q @ R.T + t), curved.to_relative(q), atol=1e-8)
    np.testing.assert_allclose(translate(curved, t).curve.points, curved.curve.points + t)


def test_rotate_about_the_start_by_default(curved):
    r = rotate(curved, [0, 0, 1], 90)
    np.testing.assert_allclose(r.curve.points[0], curved.curve.points[0], atol=1e-12)
    d_old = curved.curve.points[-1] - curved.curve.points[0]
    d_new = r.curve.points[-1] - r.curve.points[0]
    np.testing.assert_allclose(d_new, [-d_old[1], d_old[0], d_old[2]], atol=1e-12)
    assert same_shape(rotate(curved, [1, 1, 0], 360, pivot=[1, 2, 3]), curved)


@pytest.mark.parametrize("R, match", [(np.diag([1, 1, -1]), "not a rotation"),
                                      (2 * np.eye(3), "not a rotation"),
                                      (np.full((3, 3), np.nan), "NaN"),
                                      (np.eye(2), "shape")])
def test_rigid_rejects_non_rotations(curved, R, match):
    with pytest.raises(EditError, match=match):
        rigid(curved, R, [0, 0, 0])


def test_rotate_rejects_zero_axis(curved):
    with pytest.raises(EditError, match="nonzero"):
        rotate(curved, [0, 0, 0], 30)


# ---- stretch ---------------------------------------------------------------------------------
def test_stretch_straight_is_exact(straight):
    L = straight.length
    s = stretch(straight, 0.25, 0.5, 3.0)
    assert isinstance(s.curve, BezierCurve) and len(s.curve.points) == 3
    assert s.length == pytest.approx(L + 2 * 0.25 * L, rel=1e-9)
    # the joints C(t0) (stays) and C(t1) (moves out by (f - 1)(t1 - t0) L) keep their network t
    np.testing.assert_allclose(t_of(s, [[0.25, 0, 0], [0.25 + 3 * 0.25, 0, 0]]), [0.25, 0.5],
                               atol=1e-9)
    # the parameter map sends [t0, t1] onto the 3x longer arc range
    arc = s.arc_of_t(torch.tensor([0.25, 0.5, 1.0], dtype=torch.float64)).numpy() * s.length
    np.testing.assert_allclose(arc, [0.25 * L, L, 1.5 * L], rtol=1e-9)
    # keys stay at their t: the radii/twist profile over t is unchanged
    t = torch.linspace(0, 1, 101, dtype=torch.float64)
    torch.testing.assert_close(s.radii_at(t), straight.radii_at(t))


def test_stretch_moves_the_network_features_with_the_material(straight):
    """A point of the stretched piece has the relative coordinates (so the network input u) of
    the point it came from: x -> x0 + f (x - x0) inside the range, + (f - 1)(x1 - x0) after."""
    s = stretch(straight, 0.25, 0.5, 3.0)
    rel = rel_samples()
    old = straight.to_world(rel)
    x, x0, x1 = old[:, 0], 0.25, 0.5
    new = old.copy()
    new[:, 0] = np.where(x <= x0, x, np.where(x <= x1, x0 + 3 * (x - x0), x + 2 * (x1 - x0)))
    np.testing.assert_allclose(s.to_world(rel), new, atol=1e-6)  # arc-length tables
    np.testing.assert_allclose(s.to_relative(new), rel, atol=1e-7)


@pytest.mark.parametrize("kind", ["bezier", "spline"])
@pytest.mark.parametrize("t0, t1, factor", [(0.3, 0.6, 2.0), (0.0, 0.4, 1.5), (0.5, 1.0, 0.6)])
def test_stretch_curved_scales_the_range_and_keeps_the_rest(curved, kind, t0, t1, factor):
    gc = make_gc(curved.curve.points.tolist(), kind=kind) if kind == "spline" else curved
    L = gc.length
    s = stretch(gc, t0, t1, factor)
    c0, c1 = (gc.to_world(np.array([[2 * t - 1, 0.0, 0.0]]))[0] for t in (t0, t1))
    j0, j1 = c0, c0 + factor * (c1 - c0)  # where the exact map puts the joints
    Ln = s.length
    assert Ln == pytest.approx(L + (factor - 1) * (t1 - t0) * L, rel=1e-3)
    # the joints keep their network t; the arc lengths between them scale
    np.testing.assert_allclose(t_of(s, [j0, j1]), [t0, t1], atol=3e-3)
    a, b = s.arc_of_t(torch.tensor([t0, t1], dtype=torch.float64)).numpy() * Ln
    assert b - a == pytest.approx(factor * (t1 - t0) * L, rel=1e-4)  # spline fit of the map
    assert a == pytest.approx(t0 * L, rel=1e-4, abs=1e-12)
    assert Ln - b == pytest.approx((1 - t1) * L, rel=1e-4, abs=1e-12)
    # keys (and so the radii/twist profile over t) are unchanged; round trips stay exact
    assert s.keys == gc.keys
    rel = rel_samples()
    np.testing.assert_allclose(s.to_relative(s.to_world(rel)), rel, atol=1e-6)


def test_stretch_map_nodes(straight):
    tn, arc, L_new = stretch_map(straight, 0.25, 0.5, 3.0)
    np.testing.assert_allclose(tn, [0, 0.25, 0.5, 1])
    np.testing.assert_allclose(arc * L_new, np.array([0, 0.25, 1.0, 1.5]) * straight.length)


def test_stretches_compose_through_the_parameter_map(straight):
    """Stretching a range twice multiplies the factors (exact for a straight GC), and stretching
    back restores the identity map."""
    twice = stretch(stretch(straight, 0.2, 0.4, 2.0), 0.2, 0.4, 1.5)
    once = stretch(straight, 0.2, 0.4, 3.0)
    assert same_shape(twice, once, atol=1e-6)
    assert twice.length == pytest.approx(once.length, rel=1e-12)
    # a second stretch over a range that straddles the first one's node
    other = stretch(stretch(straight, 0.2, 0.4, 2.0), 0.3, 0.8, 0.5)
    np.testing.assert_allclose(other.reparam[0], [0, 0.2, 0.3, 0.4, 0.8, 1])
    rel = rel_samples()
    np.testing.assert_allclose(other.to_relative(other.to_world(rel)), rel, atol=1e-7)
    back = stretch(stretch(straight, 0.2, 0.4, 2.0), 0.2, 0.4, 0.5)
    assert back.length == pytest.approx(straight.length, rel=1e-12)
    np.testing.assert_allclose(back.reparam[1], back.reparam[0], atol=1e-12)
    assert same_shape(back, straight, atol=1e-6)  # control points re-spaced: table rounding


def test_stretched_gc_round_trips_through_its_dict(curved):
    s = stretch(curved, 0.3, 0.6, 2.0)
    again = GeneralizedCylinder.from_dict(s.to_dict())
    assert same_shape(s, again, atol=1e-7)
    assert "reparam" in s.to_dict() and "reparam" not in curved.to_dict()


def test_stretch_whole_curve_is_a_uniform_scaling(curved):
    s = stretch(curved, 0.0, 1.0, 1.7)
    assert isinstance(s.curve, BezierCurve)
    assert s.length == pytest.approx(1.7 * curved.length, rel=1e-9)
    assert [k.t for k in s.keys] == [k.t for k in curved.keys] and s.reparam is None


@pytest.mark.parametrize("args, match", [
    ((0.6, 0.4, 2.0), "empty"), ((-0.1, 0.4, 2.0), r"\[0, 1\]"), ((0.1, 1.4, 2.0), "t1 = 1.4"),
    ((0.1, 0.4, 0.0), "positive"), ((0.1, 0.4, -2), "positive"), ((0.1, 0.4, np.nan), "NaN"),
    ((np.nan, 0.4, 2), r"\[0, 1\]")])
def test_stretch_rejects_bad_arguments(curved, args, match):
    with pytest.raises(EditError, match=match) as e:
        stretch(curved, *args)
    assert "stretch" in str(e.value) and "'part'" in str(e.value)


# ---- scale radii -----------------------------------------------------------------------------
def radii(gc, t):
    return gc.radii_at(torch.as_tensor(np.atleast_1d(t), dtype=torch.float64)).numpy()


def test_scale_radii_at_a_new_key_is_local(curved):
    s = scale_radii(curved, 0.25, 2.0)
    assert [k.t for k in s.keys] == [0.0, 0.25, 0.5, 1.0]
    np.testing.assert_allclose(radii(s, 0.25), 2 * radii(curved, 0.25))
    np.testing.assert_allclose(radii(s, [0.0, 0.5, 0.7, 1.0]), radii(curved, [0.0, 0.5, 0.7, 1.0]))
    # twist profile unchanged by the inserted key
    t = torch.linspace(0, 1, 101, dtype=torch.float64)
    torch.testing.assert_close(s.twist_at(t), curved.twist_at(t))


def test_scale_radii_with_falloff_confines_the_change(curved):
    s = scale_radii(curved, 0.5, [1.5, 0.5], falloff=0.1)
    np.testing.assert_allclose(radii(s, 0.5), radii(curved, 0.5) * [1.5, 0.5])
    out = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    np.testing.assert_allclose(radii(s, out), radii(curved, out), atol=1e-12)


def test_scale_all_radii_scales_cross_section_area(curved):
    s = scale_radii(curved, None, 1.3)
    t = np.linspace(0, 1, 11)
    area = lambda g: np.pi * radii(g, t).prod(1)  # ellipse area pi r_y r_z
    np.testing.assert_allclose(area(s), 1.3 ** 2 * area(curved))
    # and the world cross-section: a point at (u, a, b) moves 1.3x as far from the curve
    rel = np.array([[0.0, 1.0, 0.0], [0.2, 0.0, -1.0]])
    foot = curved.to_world(rel * [1, 0, 0])
    np.testing.assert_allclose(s.to_world(rel) - foot, 1.3 * (curved.to_world(rel) - foot))


@pytest.mark.parametrize("t, factor, falloff, match", [
    (0.5, 0.0, None, "positive"), (0.5, -1.0, None, "positive"), (0.5, np.nan, None, "positive"),
    (1.5, 2.0, None, r"\[0, 1\]"), (0.5, [1, 2, 3], None, "pair"), (0.5, 2.0, 0.0, "positive"),
    (None, 2.0, 0.1, "needs a key t"), ("a", 2.0, None, "number")])
def test_scale_radii_rejects_bad_arguments(curved, t, factor, falloff, match):
    with pytest.raises(EditError, match=match) as e:
        scale_radii(curved, t, factor, falloff=falloff)
    assert "scale_radii" in str(e.value)


# ---- twist -----------------------------------------------------------------------------------
def test_twist_adds_at_a_key(curved):
    tw = twist(curved, 0.5, 90.0)
    assert tw.keys[1].twist == pytest.approx(130.0)
    t = torch.tensor([0.0, 0.25, 1.0], dtype=torch.float64)
    ramp = torch.tensor([0.0, 45.0, 0.0], dtype=torch.float64)
    torch.testing.assert_close(tw.twist_at(t), curved.twist_at(t) + torch.deg2rad(ramp))
    # the cross-section at t = 0.5 turned by 90 degrees about the tangent
    a = curved.to_world(np.array([[0.0, 1.0, 0.0]]))[0]
    b = tw.to_world(np.array([[0.0, 1.0, 0.0]]))[0]
    c = curved.to_world(np.array([[0.0, 0.0, 0.0]]))[0]
    assert abs((a - c) @ (b - c)) < 1e-9
    new = twist(curved, 0.3, 30.0, falloff=0.1)
    assert [k.t for k in new.keys] == pytest.approx([0.0, 0.2, 0.3, 0.4, 0.5, 1.0])


def test_twist_360_everywhere_is_no_twist(curved):
    assert same_shape(twist(curved, None, 360.0), curved)
    assert same_shape(twist(curved, None, -720.0), curved)


def test_twist_rejects_bad_arguments(curved):
    with pytest.raises(EditError, match="finite"):
        twist(curved, 0.5, np.inf)
    with pytest.raises(EditError, match=r"t = -0.2"):
        twist(curved, -0.2, 10)


# ---- composition and programs ----------------------------------------------------------------
def test_compose_equals_applying_in_order(curved):
    seq = stretch(scale_radii(twist(curved, 0.5, 45), 0.2, 1.5), 0.3, 0.6, 1.5)
    ops = [functools.partial(twist, t=0.5, degrees=45),
           {"op": "scale", "t": 0.2, "factor": 1.5},
           ("stretch", {"t0": 0.3, "t1": 0.6, "factor": 1.5})]
    assert same_shape(compose(curved, ops), seq)
    assert compose(curved, []) is curved


def test_apply_rejects_unknown_op_and_bad_parameters(curved):
    with pytest.raises(EditError, match="unknown op"):
        apply(curved, "squash", factor=2)
    with pytest.raises(EditError, match="bad parameters") as e:
        apply(curved, "twist", t=0.5, angle=3)
    assert "'degrees'" in str(e.value)


def test_edits_round_trip_through_dicts(curved):
    edited = compose(curved, [{"op": "move", "indices": [2], "offsets": [0, 0.1, 0]},
                              {"op": "twist", "t": 0.8, "degrees": 30}])
    again = GeneralizedCylinder.from_dict(edited.to_dict())
    assert same_shape(edited, again, atol=1e-12)
    assert math.isclose(again.keys[-2].twist, edited.keys[-2].twist)


# ---- twist ramp, local motion ----------------------------------------------------------------
def test_twist_ramp_adds_a_linear_ramp(curved):
    r = twist_ramp(curved, 0.2, 0.8, 90.0)
    t = torch.linspace(0, 1, 101, dtype=torch.float64)
    ramp = torch.clamp((t - 0.2) / 0.6, 0, 1) * math.radians(90.0)
    torch.testing.assert_close(r.twist_at(t), curved.twist_at(t) + ramp)
    torch.testing.assert_close(r.radii_at(t), curved.radii_at(t))
    with pytest.raises(EditError, match="empty"):
        twist_ramp(curved, 0.5, 0.5, 10)


def test_local_motion_of_a_rigid_edit_is_that_motion(curved):
    R = Rotation.from_rotvec([0.2, 0.5, -0.3]).as_matrix()
    t = np.array([0.1, -0.2, 0.3])
    moved = rigid(curved, R, t)
    p = curved.to_world(np.array([[0.3, 0.5, -0.2]]))[0]
    Rl, tl = local_motion(curved, moved, p)
    np.testing.assert_allclose(Rl, R, atol=1e-9)
    np.testing.assert_allclose(tl, t, atol=1e-9)


def test_local_motion_follows_a_stretch_by_translation(straight):
    s = stretch(straight, 0.2, 0.5, 2.0)
    R, t = local_motion(straight, s, np.array([0.8, 0.05, 0.0]))  # after the range
    np.testing.assert_allclose(R, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(t, [0.3, 0, 0], atol=1e-6)
