"""Cameras of the pictures: the up setting and its detection, the side view about up, the edit
view across the motion, and a framing that keeps every point inside the image."""
import math

import numpy as np
import pytest
import trimesh

from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.viz import gc_labels
from ngc_gen.viz.camera import (ELEVATION, MIN_ELEVATION, camera_distance, curve_displacements,
                                detect_up, edit_view, frame_points, least_motion_view,
                                resolve_up, side_view, up_vector)

from ..conftest import straight_gc

X, Y, Z = np.eye(3)


def quadruped() -> trimesh.Trimesh:
    """A z-up animal: a rounded body on four legs, a head at +x (as the creatures)."""
    def ellipsoid(radii, at):
        m = trimesh.creation.icosphere(subdivisions=2)
        m.apply_scale(radii)
        return m.apply_translation(at)

    parts = [ellipsoid((0.8, 0.3, 0.2), (0, 0, 1.0)), ellipsoid((0.18, 0.18, 0.18), (0.9, 0, 1.3))]
    parts += [trimesh.creation.cylinder(radius=0.06, height=1.0, transform=_at(x, y, 0.5))
              for x in (-0.6, 0.6) for y in (-0.2, 0.2)]
    return trimesh.util.concatenate(parts)


def _at(x, y, z):
    return trimesh.transformations.translation_matrix((x, y, z))


def rotated(points, up) -> np.ndarray:
    """Points rotated so that +z goes to `up`."""
    R = trimesh.geometry.align_vectors(Z, up)[:3, :3]
    return np.asarray(points, dtype=float) @ R.T


def turned(mesh: trimesh.Trimesh, up) -> np.ndarray:
    """The mesh's vertices rotated so that its +z goes to `up`."""
    return rotated(mesh.vertices, up)


@pytest.mark.parametrize("spec, want", [("y", Y), ("-z", -Z), ("+x", X), (" Y ", Y),
                                        ([0, 2, 0], Y), ((0.0, 0.0, -3.0), -Z)])
def test_up_setting_names_an_axis_or_a_vector(spec, want):
    assert np.allclose(up_vector(spec), want)
    assert up_vector("auto") is None


@pytest.mark.parametrize("bad", ["w", "--y", "yz", [0, 0, 0], [1, 2], "up"])
def test_a_bad_up_setting_says_where_to_fix_it(bad):
    with pytest.raises(ValueError, match="viz.up"):
        up_vector(bad)


@pytest.mark.parametrize("up", [Z, Y, -Y, X, -X, -Z])
def test_a_shape_standing_on_feet_gets_its_up_in_any_orientation(up):
    assert np.allclose(detect_up(turned(quadruped(), up)), up)


def test_rules_for_flat_and_baseless_shapes():
    plate = trimesh.creation.box(extents=(2.0, 0.1, 1.5))  # lies in xz: seen from +y
    assert np.allclose(detect_up(plate.vertices), Y)
    assert np.allclose(detect_up(trimesh.creation.box().vertices), Z)  # no evidence: z
    rod = trimesh.creation.cylinder(radius=0.1, height=2.0)
    rod_x = turned(rod, X)
    assert np.allclose(detect_up(rod_x), Z)  # a rod has no base, and is not flat
    sheet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]])
    assert np.allclose(detect_up(sheet.vertices), Z)  # zero thickness: flat


def test_the_shipped_y_up_ant_is_detected_y_up():
    from ngc_gen.data.mesh.io import load_mesh

    ant = load_mesh("pyvista:ant.ply")  # the ant of datasets/ant: legs toward -y
    assert np.allclose(detect_up(ant.vertices), Y)
    assert np.allclose(resolve_up("auto", [ant, None]), Y)
    assert np.allclose(resolve_up("z", [ant]), Z)  # a setting wins over the detection


def test_auto_up_of_several_meshes_is_the_most_common():
    q = quadruped()
    y_up = trimesh.Trimesh(turned(q, Y), q.faces)
    assert np.allclose(resolve_up("auto", [q, y_up, y_up]), Y)
    assert np.allclose(resolve_up("auto", [q, y_up]), Z)  # a tie: the first mesh's
    assert np.allclose(resolve_up("auto", []), Z)


def test_side_view_is_the_old_default_for_z_up_and_turns_with_up():
    long_x = np.array([[-2, -0.5, 0], [2, 0.5, 1.0]])
    d = side_view(long_x, Z)
    assert np.allclose(d, np.array([1, -1.6, 0.9]) / np.linalg.norm([1, -1.6, 0.9]), atol=1e-3)
    for up in (Y, -Y, X):
        d = side_view(rotated(long_x, up), up)
        assert math.isclose(d @ up, math.sin(math.radians(ELEVATION)), abs_tol=1e-9)


def _elevation(d, up):
    return math.degrees(math.asin(d @ up / np.linalg.norm(d)))


@pytest.mark.parametrize("up", [Z, Y])
def test_edit_view_is_perpendicular_to_a_motion_toward_the_camera(up):
    ref = side_view(np.array([[-1, -1, -1], [2, 1, 1]]), up)
    toward = ref - (ref @ up) * up  # the raised head came straight at the default camera
    for motion in (toward, toward + 0.3 * up, np.cross(up, toward)):
        d = least_motion_view(np.tile(motion, (5, 1)), up, ref)
        assert abs(d @ motion) / np.linalg.norm(motion) < 0.01, motion
        assert MIN_ELEVATION - 1e-6 <= _elevation(d, up) <= ELEVATION + 1e-6
    d = least_motion_view(np.tile(toward, (5, 1)), up, ref)
    assert math.isclose(_elevation(d, up), ELEVATION, abs_tol=0.3)  # still from above
    assert np.allclose(least_motion_view(np.zeros((3, 3)), up, ref), ref)  # nothing moved
    vertical = least_motion_view(np.tile(up, (4, 1)), up, ref)
    assert math.isclose(_elevation(vertical, up), MIN_ELEVATION, abs_tol=0.3)


def test_edit_view_follows_the_moved_gcs():
    gcs = [GeneralizedCylinder.from_dict(straight_gc(n, x, x + 0.5, (0.1, 0.1), (0.1, 0.1)))
           for n, x in (("body", -0.5), ("head", 0.0))]
    ref = side_view(np.array([[-0.6, -0.2, -0.2], [0.6, 0.2, 0.2]]), Z)
    shift = np.array([ref[0], ref[1], 0.0]) * 0.3  # the head toward the default camera
    moved = [gcs[0], GeneralizedCylinder.from_dict(
        {**straight_gc("head", 0.0, 0.5, (0.1, 0.1), (0.1, 0.1)),
         "curve": {"type": "bezier", "points": [(np.array([0.0, 0, 0]) + shift).tolist(),
                                                (np.array([0.5, 0, 0]) + shift).tolist()]}})]
    disp = curve_displacements(gcs, moved)
    assert disp.shape == (2 * 33, 3)
    assert np.allclose(disp[:33], 0) and np.allclose(disp[33:], shift)
    d = edit_view(np.array([[-0.6, -0.2, -0.2], [0.6, 0.2, 0.2]]), gcs, moved, Z)
    assert abs(d @ shift) / np.linalg.norm(shift) < 0.01
    assert abs(ref @ shift) / np.linalg.norm(shift) > 0.8  # the old camera looked along it



def _leg(name, points):
    return GeneralizedCylinder.from_dict(
        {"name": name, "curve": {"type": "bezier", "points": np.asarray(points).tolist()},
         "up": [1.0, 0.0, 0.0], "keys": [{"t": 0.0, "radii": [0.05, 0.05], "twist": 0.0}],
         "caps": [0.05, 0.05]})


def test_edit_view_stands_on_the_moved_parts_side():
    """A back leg (out along +y, then down) raised by 45 degrees about x turns in the (y, z)
    plane: the cameras across it look from +x or from -x. The side view's tie-break takes +x,
    across the body that hides the leg; the edit view takes the -x side, where the leg is, and
    hides no more of the motion."""
    body = GeneralizedCylinder.from_dict(straight_gc("body", -0.6, 0.6, (0.2, 0.2), (0.1, 0.1)))
    hip, a = np.array([-0.3, 0.1, 0.0]), math.radians(45)
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    leg = hip + np.array([[0, 0, 0], [0, 0.3, 0], [0, 0.5, -0.3]])
    before = [body, _leg("leg", leg)]
    after = [body, _leg("leg", hip + (leg - hip) @ R.T)]
    points = np.array([[-0.7, -0.2, -0.4], [0.7, 0.6, 0.5]])
    disp = curve_displacements(before, after)
    ref = side_view(points, Z)
    across = least_motion_view(disp, Z, ref)  # without the side: across the body
    d = edit_view(points, before, after, Z)
    assert across @ X > 0.5 and d @ X < -0.5
    M = disp.T @ disp  # the motion is mirror-symmetric in x: as little of it is hidden
    assert d @ M @ d <= across @ M @ across + 1e-4 * np.trace(M)
    assert math.isclose(_elevation(d, Z), MIN_ELEVATION, abs_tol=0.3)


@pytest.mark.parametrize("seed", range(4))
def test_framing_keeps_every_point_inside_the_image(seed):
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(500, 3)) * rng.uniform(0.05, 3.0, size=3) + rng.normal(size=3)
    up = Z if seed % 2 else Y
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    aspect, fill = 320 / 260, (0.92, 0.8)
    for c, D in ((P.mean(0), camera_distance(P, P.mean(0), d, up, aspect, fill=fill)),
                 frame_points(P, d, up, aspect, fill=fill)):
        t = up - (up @ d) * d
        t /= np.linalg.norm(t)
        r = np.cross(d, t)
        Q = P - (c + D * d)
        depth = -(Q @ d)
        assert depth.min() > 0
        tan_v = math.tan(math.radians(15))
        x, y = np.abs(Q @ r) / depth / (tan_v * aspect), np.abs(Q @ t) / depth / tan_v
        assert x.max() <= fill[0] + 1e-9 and y.max() <= fill[1] + 1e-9
        assert max(x.max() / fill[0], y.max() / fill[1]) > 0.999  # tight: one side touches


def test_gc_labels_are_the_names_at_the_curve_middles():
    gcs = [GeneralizedCylinder.from_dict(straight_gc("tail", 0.0, 1.0)),
           GeneralizedCylinder.from_dict(straight_gc("head", 2.0, 4.0))]
    labels = gc_labels(gcs)
    assert [n for n, _ in labels] == ["tail", "head"]
    assert np.allclose([p for _, p in labels], [[0.5, 0, 0], [3.0, 0, 0]])
