"""One body frame for a collection: a quadruped turned any way is found upright with its names
right, given axes that are wrong are overruled with a warning, the checks refuse a match that
puts the head behind the torso, the annotation's `frame` key is validated and turns the mesh,
and a frame override naming an axis that does not exist is one line."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ngc_gen.data.annotations import Annotation, annotation_from_dict
from ngc_gen.data.autogc.frame import angle_deg, moved_gcs, read_override, wahba
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
from ngc_gen.data.autogc.transfer.verify import verify
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import normalize

from ...helpers import ROOT
from .shapes import quadruped

pytestmark = pytest.mark.usefixtures("single_thread")
TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
FAST = TransferSettings.from_yaml(resolution=64, samples=5000)


@pytest.fixture(scope="module")
def template():
    return load_template(TEMPLATE)


def test_a_quadruped_turned_any_way_is_found_upright_with_its_names(template):
    """A random rotation (not axis-aligned), no axes given: the rotation written takes the mesh
    back to the template's frame (y up, +z front) within 20 degrees, each named point lies in
    the GC of its name, and the GCs written in that frame have the template's up vectors."""
    Q = Rotation.random(random_state=3).as_matrix()
    mesh, pts = quadruped(rotation=Q)
    m, center, scale = normalize(mesh)
    tr = transfer_template(m, template, FAST, "turned")
    assert angle_deg(tr.rotation @ Q) < 20.0 and tr.source == "detected"
    assert 0.0 <= tr.confidence <= 1.0
    by = {g.name: g for g in tr.gcs}
    for point, gc in (("foot_fl", "leg_fl"), ("head_tip", "head"), ("tail_tip", "tail")):
        assert bool(by[gc].contains(((pts[point] - center) * scale)[None])[0]), (point, gc)
    ups = [g.to_dict()["up"] for g in moved_gcs(tr.gcs, tr.rotation, np.zeros(3), 1.0)]
    assert np.allclose(ups, [t.up for t in template.gcs], atol=1e-6)


def test_given_axes_that_do_not_hold_are_overruled_with_a_warning(template):
    """The user says front is -z for a quadruped facing +z: the given frame puts the head on the
    tail and fails the checks; the detected frame wins, and the warning says so."""
    m, _, _ = normalize(quadruped()[0])
    tr = transfer_template(m, template, dataclasses.replace(FAST, up="+y", front="-z"), "backwards")
    assert tr.warnings and "overruled" in tr.warnings[0]
    assert angle_deg(tr.rotation) < 20.0  # the mesh already faces the template's way


def test_the_checks_refuse_a_head_behind_the_torso(template):
    """Paths in body coordinates: legs down, head and neck in front, tail behind pass; the head
    and neck moved behind the torso fail the `ends` check, a left leg right of its partner the
    `sides` check, a tail holding more surface than neck and head the `weight` check (a frame
    turned back to front)."""
    nodes, paths, k = [], {}, 0

    def add(name, a, b):
        nonlocal k
        nodes.extend(np.linspace(a, b, 5))
        paths[name] = np.arange(k, k + 5)
        k += 5

    add("torso", (-0.6, 0, 0.2), (0.2, 0, 0.2))
    add("neck", (0.3, 0, 0.2), (0.6, 0, 0.6))
    add("head", (0.6, 0, 0.6), (0.9, 0, 0.5))
    add("tail", (-0.6, 0, 0.2), (-0.9, 0, 0.0))
    for name, f, s in (("leg_fl", 0.3, 0.5), ("leg_fr", 0.3, -0.5), ("leg_bl", -0.6, 0.5),
                       ("leg_br", -0.6, -0.5)):
        add(name, (f, s, 0.0), (f, s, -0.9))
    nodes = np.asarray(nodes, dtype=float)
    held = dict(zip(template.names, [0.4, 0.12, 0.08, 0.04, 0.09, 0.09, 0.09, 0.09]))
    surface = np.array([held[n] for n in template.names])
    assert verify(template, paths, nodes, surface).ok
    back = nodes.copy()
    back[np.r_[paths["neck"], paths["head"]], 0] *= -1.0
    assert verify(template, paths, back, surface).failed.startswith("ends: neck")
    crossed = nodes.copy()
    crossed[paths["leg_fl"], 1] *= -1.0
    crossed[paths["leg_fr"], 1] *= -1.0
    assert verify(template, paths, crossed, surface).failed.startswith("sides: leg_fl")
    heavy_tail = np.array([{**held, "tail": 0.3}[n] for n in template.names])
    assert verify(template, paths, nodes, heavy_tail).failed.startswith("weight: neck and head")


def test_wahba_recovers_a_rotation():
    Q = Rotation.random(random_state=0).as_matrix()
    body = np.random.default_rng(0).normal(size=(6, 3))
    assert angle_deg(wahba(body @ Q, body, np.ones(6)) @ Q.T) < 1e-4


def test_the_frame_key_turns_the_mesh_and_is_checked(tmp_path):
    import trimesh

    box = trimesh.creation.box((2.0, 1.0, 0.5))
    box.export(tmp_path / "box.ply")
    R = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    d = {"name": "box", "mesh": str(tmp_path / "box.ply"),
         "gcs": [{"name": "a", "curve": {"type": "bezier", "points": [[0, -0.5, 0], [0, 0.5, 0]]},
                  "up": [0, 0, 1], "keys": [{"t": 0, "radii": [0.2, 0.2]}], "caps": [0.1, 0.1]}],
         "frame": {"up": [0, 1, 0], "front": [0, 0, 1], "from_mesh": R.tolist(),
                   "source": "detected"}}
    ann = annotation_from_dict(d)
    mesh, _, _ = ann.load_mesh()
    ext = np.ptp(np.asarray(mesh.vertices), axis=0)
    assert ext[1] > ext[0]  # the box's long side turned from x to y
    assert annotation_from_dict(ann.to_dict()).frame == ann.frame
    for bad in ({**d["frame"], "from_mesh": (2 * R).tolist()}, {**d["frame"], "source": "guess"},
                {"up": "+y", "front": "+z"}):
        with pytest.raises(DataError, match="frame"):
            annotation_from_dict({**d, "frame": bad})
    assert isinstance(Annotation("x", "m.ply", ann.gcs).to_dict().get("frame", None), type(None))


def test_a_frame_override_naming_no_axis_is_one_line(tmp_path):
    (tmp_path / "cow.ply").write_text("")
    (tmp_path / "frames.yaml").write_text("'*': {up: +w, front: +z}\n")
    with pytest.raises(DataError) as e:
        read_override(tmp_path / "cow.ply")
    assert "frames.yaml" in str(e.value) and e.value.field == "frame.up"
    assert "\n" not in str(e.value)
    (tmp_path / "frames.yaml").write_text("cow: {up: +y, front: -z}\n")
    o, where = read_override(tmp_path / "cow.ply")
    assert o.up.tolist() == [0, 1, 0] and o.front.tolist() == [0, 0, -1]
    assert read_override(tmp_path / "pig.ply") == (None, None)


def test_body_frames_from_the_hulls_points_are_the_surfaces():
    """orientation.choose builds a body frame per candidate from the surface's extreme points
    only: the same bounding box in every frame as from all of them."""
    from ngc_gen.data.autogc.frame import pca_candidates
    from ngc_gen.data.autogc.transfer.tree import BodyFrame, extreme_points

    X = np.random.default_rng(0).normal(size=(20000, 3)) * [3.0, 2.0, 1.0]
    E = extreme_points(X)
    assert len(E) < len(X) // 20
    for o in pca_candidates(X @ np.linalg.qr(np.ones((3, 3)) + np.eye(3))[0]):
        a, b = BodyFrame.of(X, o), BodyFrame.of(E, o)
        np.testing.assert_array_equal(a.center, b.center)
        np.testing.assert_array_equal(a.half, b.half)
    flat = X * [1.0, 1.0, 0.0]                         # no hull: every point
    assert len(extreme_points(flat)) == len(flat)
