"""Calibrated ends: a template records where its annotator ends each part (`start_at`,
`end_at`, relative coordinates of the transferred GC), the transfer puts the ends there, and the
fields survive a YAML round trip and are checked on load."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from ngc_gen.data.autogc.calibrate import calibrate_ends, without_ends
from ngc_gen.data.autogc.template import load_template, template_from_dict
from ngc_gen.data.autogc.transfer import TransferSettings, _moved_ends, transfer_template
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import normalize
from ngc_gen.geometry import GeneralizedCylinder

from ...helpers import ROOT
from .shapes import quadruped

pytestmark = pytest.mark.usefixtures("single_thread")
TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
FAST = TransferSettings.from_yaml(resolution=64, samples=5000)
ENDS = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])


def _straight_gc() -> GeneralizedCylinder:
    return GeneralizedCylinder.from_dict({
        "name": "g", "curve": {"type": "bezier", "points": [[0, 0, 0], [0.5, 0, 0], [1, 0, 0]]},
        "up": [0, 0, 1], "keys": [{"t": 0.0, "radii": [0.1, 0.1]}, {"t": 1.0, "radii": [0.1, 0.1]}],
        "caps": [0.05, 0.05]})


def test_moved_ends_land_on_the_relative_coordinates():
    gc = _straight_gc()
    place = {"start_at": (-1.0, 1.0, 0.0), "end_at": (0.5, 0.0, 0.0)}   # up (a: along N) one radius; 3/4 along
    poly = _moved_ends(gc, place)
    np.testing.assert_allclose(poly[0], [0.0, 0.0, 0.1], atol=1e-6)
    np.testing.assert_allclose(poly[-1], [0.75, 0.0, 0.0], atol=1e-3)
    unmoved = _moved_ends(gc, {})
    np.testing.assert_allclose(unmoved[[0, -1]], [[0, 0, 0], [1, 0, 0]], atol=1e-6)


def _with_start_moved(gc: GeneralizedCylinder, offset) -> GeneralizedCylinder:
    d = gc.to_dict()
    pts = np.asarray(d["curve"]["points"], dtype=np.float64)
    pts[0] += offset
    d["curve"]["points"] = pts.tolist()
    return GeneralizedCylinder.from_dict(d)


def test_a_calibrated_template_ends_parts_where_the_annotation_does():
    """The annotation starts a front leg higher and farther out than the skeleton does (a rig's
    shoulder joint); calibrated on that annotated mesh, the transfer starts it there too."""
    template = without_ends(load_template(TEMPLATE))
    mesh, _ = quadruped()
    mesh, _, _ = normalize(mesh)
    plain = transfer_template(mesh, template, FAST, "plain")
    i = plain.matched.index("leg_fl")
    truth = list(plain.gcs)
    truth[i] = _with_start_moved(truth[i], [0.06, 0.05, 0.0])   # y up, +z front: up, out (+x)
    calibrated = calibrate_ends(template, [("annotated", mesh, truth)], FAST)
    assert "start_at" in calibrated.gc("leg_fl").place
    after = transfer_template(mesh, calibrated, FAST, "calibrated")
    want = np.asarray(truth[i].to_world(ENDS))
    before_err = np.linalg.norm(np.asarray(plain.gcs[i].to_world(ENDS))[0] - want[0])
    after_err = np.linalg.norm(np.asarray(after.gcs[i].to_world(ENDS))[0] - want[0])
    assert before_err > 0.07 and after_err < 0.3 * before_err, (before_err, after_err)
    # the annotation's own ends elsewhere are the transfer's: nothing else moves much
    torso = plain.matched.index("torso")
    moved = np.linalg.norm(np.asarray(after.gcs[torso].to_world(ENDS)) -
                           np.asarray(plain.gcs[torso].to_world(ENDS)), axis=1)
    assert moved.max() < 0.02, moved


def test_ends_round_trip_and_bad_ones_are_refused(tmp_path):
    t = load_template(TEMPLATE)
    assert all("start_at" in g.place and "end_at" in g.place for g in t.gcs)  # the shipped one
    path = tmp_path / "t.yaml"
    path.write_text(t.to_yaml())
    back = load_template(path)
    np.testing.assert_allclose(back.gc("leg_fl").place["start_at"], t.gc("leg_fl").place["start_at"])
    d = yaml.safe_load(t.to_yaml())
    d["gcs"][0]["place"]["start_at"] = [0.0, 1.0]
    with pytest.raises(DataError, match="start_at") as e:
        template_from_dict(d, "bad.yaml")
    assert "bad.yaml" in str(e.value) and "\n" not in str(e.value)


def test_the_calibrated_end_lands_in_the_largest_cluster_not_between():
    """Annotated ends in three clusters around a part's tip (4, 3 and 2 meshes, 0.3 of its
    length out to three sides): the calibrated end is the four's. The per-coordinate median
    (and the point of least median distance) lies at the tip itself, 0.3 from every annotated
    end: within the tolerance of none."""
    from ngc_gen.data.autogc.calibrate import TOLERANCE, _best

    gcs = [_straight_gc()] * 9
    sides = [[0.0, 0.3, 0.0]] * 4 + [[0.0, 0.0, 0.3]] * 3 + [[0.0, -0.3, -0.3]] * 2
    truth = np.array([1.0, 0.0, 0.0]) + np.array(sides) + 0.005 * np.arange(9)[:, None]
    rel = np.asarray(gcs[0].to_relative(truth))
    cands = np.concatenate([rel, np.median(rel, axis=0)[None]])
    chosen = np.asarray(gcs[0].to_world(_best(cands, gcs, truth, np.ones(9))[None]))[0]
    hits = np.linalg.norm(truth - chosen, axis=1) <= TOLERANCE
    assert hits[:4].all() and not hits[4:].any(), (chosen, hits)
    # the one mesh case: its own end
    np.testing.assert_allclose(_best(rel[5:6], gcs[:1], truth[5:6], np.ones(1)), rel[5])
