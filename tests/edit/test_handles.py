import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.edit import EditError, deform_by_handles, hermite_of_length, kabsch
from ngc_gen.edit.handles import cubic_length
from ngc_gen.geometry import BezierCurve, GeneralizedCylinder

ZERO = torch.zeros(1, dtype=torch.float64)
ONE = torch.ones(1, dtype=torch.float64)


def gc(points, name="bar", kind="bezier", up=(0, 0, 1), radii=(0.08, 0.06), twist=0.0):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": kind, "points": points}, "up": list(up),
        "keys": [{"t": 0.0, "radii": list(radii), "twist": twist},
                 {"t": 1.0, "radii": [r * 0.8 for r in radii], "twist": -twist}],
        "caps": [0.05, 0.05]})


def end_handles(g, end=1, n=6, seed=0):
    """Handle points around the `end` cross-section, half of them in the end cap."""
    rng = np.random.default_rng(seed)
    sign = 1.0 if end else -1.0
    u = sign * np.where(np.arange(n) % 2, 1.0, rng.uniform(1.0, 1.6, n))
    ang = rng.uniform(0, 2 * np.pi, n)
    rel = np.stack([u, 0.7 * np.cos(ang), 0.7 * np.sin(ang)], 1)
    return g.to_world(rel)


def frame(g, s):
    return np.concatenate([v.numpy() for v in g.frame(s, s)])  # rows C, T, N, B


def check_handles(old, new, handles, targets, tol=1e-3):
    moved = new.to_world(old.to_relative(handles))
    assert np.abs(moved - targets).max() < tol
    assert new.length == pytest.approx(old.length, rel=1e-3)


# ---- rigid fit -------------------------------------------------------------------------------
def test_kabsch_recovers_a_rigid_motion():
    rng = np.random.default_rng(1)
    src = rng.normal(size=(7, 3))
    R = Rotation.random(random_state=3).as_matrix()
    t = np.array([0.3, -1.0, 2.0])
    R2, t2 = kabsch(src, src @ R.T + t)
    np.testing.assert_allclose(R2, R, atol=1e-10)
    np.testing.assert_allclose(t2, t, atol=1e-10)
    R1, t1 = kabsch(src[:1], src[:1] + t)  # one handle: a translation
    np.testing.assert_allclose(R1, np.eye(3))
    np.testing.assert_allclose(t1, t, atol=1e-12)
    line = np.array([[0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])  # collinear: rotation between lines
    Rz = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    R3, t3 = kabsch(line, line @ Rz.T)
    np.testing.assert_allclose(line @ R3.T + t3, line @ Rz.T, atol=1e-12)


# ---- Roulier & Piper -------------------------------------------------------------------------
def test_hermite_keeps_a_straight_bar_straight():
    x = np.array([1.0, 0, 0])
    ctrl, alpha, got = hermite_of_length([0, 0, 0], x, [2, 0, 0], x, 2.0)
    assert alpha == pytest.approx(2 / 3) and got == pytest.approx(2.0, rel=1e-12)


def test_hermite_hits_the_length_and_reports_the_unreachable():
    ctrl, alpha, got = hermite_of_length([0, 0, 0], [1, 0, 0], [0.5, 0.5, 0], [0, 1, 0], 1.0)
    assert cubic_length(ctrl) == pytest.approx(1.0, rel=1e-10) and alpha > 0
    with pytest.raises(EditError, match=r"1\.5 from the fixed end but the curve is 1 long") as e:
        hermite_of_length([0, 0, 0], [1, 0, 0], [1.5, 0, 0], [1, 0, 0], 1.0, gc_name="tail")
    assert "'tail'" in str(e.value) and "Fix:" in str(e.value)
    with pytest.warns(UserWarning, match="not reachable"):
        ctrl, _, got = hermite_of_length([0, 0, 0], [1, 0, 0], [1.5, 0, 0], [0, 1, 0], 1.0,
                                         on_unreachable="closest")
    assert got > 1.0


# ---- bends of a straight bar -----------------------------------------------------------------
@pytest.mark.parametrize("degrees", [90, 180])
def test_bend_a_straight_bar(degrees):
    bar = gc([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    L = bar.length
    theta = np.radians(degrees)
    rho = L / theta  # an arc of length L turning by theta ends at (rho sin, rho (1 - cos))
    end_new = np.array([rho * np.sin(theta), rho * (1 - np.cos(theta)), 0.0])
    Rz = Rotation.from_euler("z", degrees, degrees=True).as_matrix()
    h = end_handles(bar)
    targets = (h - [1.0, 0, 0]) @ Rz.T + end_new
    fixed = np.array([[-0.05, 0, 0], [0.0, 0.05, 0.0]])
    (new,), info = deform_by_handles([bar], h, targets, fixed, return_info=True)
    assert isinstance(new.curve, BezierCurve) and new.curve.degree == 3
    check_handles(bar, new, h, targets)
    assert new.length == pytest.approx(L, rel=1e-3)
    # fixed end exactly unchanged: point and frame
    np.testing.assert_array_equal(new.curve.points[0], bar.curve.points[0])
    np.testing.assert_allclose(frame(new, ZERO), frame(bar, ZERO), atol=1e-12)
    # moved end: rotated tangent, planar bend needs no extra twist
    np.testing.assert_allclose(frame(new, ONE)[1], Rz @ frame(bar, ONE)[1], atol=1e-9)
    assert abs(info.bent["bar"]["twist_added"]) < 1e-6 and info.bent["bar"]["moving_end"] == 1
    assert new.keys == bar.keys


def test_fixed_end_at_the_curve_end_and_a_3d_drag():
    g = gc([[0, 0, 0], [0.4, 0.2, 0.1], [0.8, -0.1, 0.3], [1.1, 0.2, 0.2]], twist=30)
    R = Rotation.from_euler("xyz", [40, -25, 30], degrees=True).as_matrix()
    h = end_handles(g, end=0)
    start = g.curve.points[0]
    targets = (h - start) @ R.T + start + [0.25, 0.1, -0.2]
    fixed = lambda p: p[:, 0] > 1.0  # noqa: E731  (a fixed-region predicate)
    (new,), info = deform_by_handles([g], h, targets, fixed, return_info=True)
    assert info.bent["bar"]["moving_end"] == 0
    check_handles(g, new, h, targets)
    np.testing.assert_array_equal(new.curve.points[-1], g.curve.points[-1])
    np.testing.assert_allclose(frame(new, ONE), frame(g, ONE), atol=1e-9)
    assert info.bent["bar"]["twist_added"] != 0  # non-planar: roll matched by a twist ramp


def test_spline_becomes_a_cubic_and_keeps_its_length():
    g = gc([[0, 0, 0], [0.3, 0.1, 0], [0.6, -0.05, 0.05], [1.0, 0.0, 0.0]], kind="spline")
    h = end_handles(g)
    end = g.to_world(np.array([[1.0, 0, 0]]))[0]
    R = Rotation.from_euler("y", -50, degrees=True).as_matrix()
    targets = (h - end) @ R.T + end + [-0.2, 0.0, 0.3]
    (new,) = deform_by_handles([g], h, targets, fixed=np.zeros((1, 3)))
    assert new.curve.kind == "bezier" and new.curve.degree == 3
    check_handles(g, new, h, targets)


def test_unreachable_target_is_a_clear_error():
    bar = gc([[0, 0, 0], [1.0, 0, 0]])
    h = end_handles(bar)
    with pytest.raises(EditError, match="no curve of the same arc length") as e:
        deform_by_handles([bar], h, h + [0.5, 0.3, 0], fixed=np.zeros((1, 3)))
    assert "'bar'" in str(e.value)


# ---- several GCs -----------------------------------------------------------------------------
def creature():
    body = gc([[-0.6, 0, 0], [0.0, 0, 0]], name="body", radii=(0.2, 0.2))
    leg = gc([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]], name="leg")
    foot = gc([[1.0, 0, 0], [1.0, 0, -0.3]], name="foot", up=(1, 0, 0), radii=(0.05, 0.04))
    toe = gc([[1.0, 0, -0.3], [1.15, 0, -0.3]], name="toe", radii=(0.03, 0.03))
    return [body, leg, foot, toe]


def test_attached_gcs_follow_rigidly_and_the_rest_stays():
    gcs = creature()
    body, leg, foot, toe = gcs
    # handles at the ankle: inside both leg (its moving end) and foot (its start)
    h = leg.to_world(np.array([[1.0, 0.5, 0.0], [1.3, 0.0, 0.5], [1.0, -0.4, -0.4]]))
    Rz = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    rho = 1.0 / (np.pi / 2)
    targets = (h - [1.0, 0, 0]) @ Rz.T + [rho, rho, 0]
    out, info = deform_by_handles(gcs, h, targets, fixed=np.array([[-0.6, 0, 0]]),
                                  return_info=True)
    assert list(info.bent) == ["leg"]
    assert info.followers == {"foot": "leg", "toe": "leg"}
    assert out[0] is body
    check_handles(leg, out[1], h, targets)
    for old, new in zip(gcs[2:], out[2:]):  # points of foot and toe keep relative coordinates
        q = old.to_world(np.array([[0.0, 0.5, 0.5], [1.5, 0.1, -0.2], [-1.2, 0.0, 0.3]]))
        moved = (q - [1.0, 0, 0]) @ Rz.T + [rho, rho, 0]
        np.testing.assert_allclose(new.to_relative(moved), old.to_relative(q), atol=1e-6)


def test_explicit_attachment_and_fixed_gcs_never_follow():
    gcs = creature()
    h = gcs[1].to_world(np.array([[1.2, 0.0, 0.0], [1.0, 0.5, 0.5]]))
    out, info = deform_by_handles(gcs, h, h + [-0.1, 0.2, 0.0], fixed=np.array([[-0.6, 0, 0]]),
                                  attached={"leg": ["foot"]}, return_info=True)
    assert info.followers == {"foot": "leg"} and out[3] is gcs[3]
    with pytest.raises(EditError, match="unknown GC 'paw'"):
        deform_by_handles(gcs, h, h, attached={"leg": ["paw"]})


@pytest.mark.parametrize("kwargs, match", [
    ({"handles": [[5.0, 5.0, 5.0]], "targets": [[5.0, 5.0, 6.0]]}, "lies in no GC"),
    ({"handles": [[1.0, 0, 0]], "targets": [[1.0, 0, 0], [1, 1, 1]]}, "as many targets"),
    ({"handles": [[1.0, np.nan, 0]], "targets": [[1.0, 0, 0]]}, "NaN"),
    ({"handles": [[1.0, 0, 0]], "targets": [[1.0, 0, 0]], "on_unreachable": "x"}, "'raise'"),
])
def test_bad_handle_inputs(kwargs, match):
    with pytest.raises(EditError, match=match):
        deform_by_handles(creature(), **kwargs)


def test_fixed_points_inside_a_gc_pin_the_end_they_lie_at():
    """A part rooted deep inside a fixed body (a tail in a torso): the fixed points near its
    root lie inside it, far from the root point itself but at small t, so the root stays and
    the far end moves, although the far end is nearer the fixed points in space."""
    tail = gc([[0, 0, 0], [0.3, 0, 0.1], [0.6, 0, 0.0]], name="tail", radii=(0.1, 0.1))
    # fixed points: a ring around the root (inside the tail, t ~ 0) and a point right next to
    # the tail's tip (outside the tail)
    ring = tail.to_world(np.array([[-0.95, 0.8 * np.cos(a), 0.8 * np.sin(a)]
                                   for a in np.linspace(0, 6, 8)]))
    fixed = np.concatenate([ring, [[0.6, 0.0, 0.3]]])
    h = end_handles(tail, end=1)
    R = Rotation.from_rotvec([0, -0.4, 0]).as_matrix()
    p0 = tail.curve.points[0]
    targets = (h - p0) @ R.T + p0
    (new,), info = deform_by_handles([tail], h, targets, fixed, return_info=True)
    assert info.bent["tail"]["moving_end"] == 1
    np.testing.assert_allclose(new.curve.points[0], p0)
    check_handles(tail, new, h, targets)
