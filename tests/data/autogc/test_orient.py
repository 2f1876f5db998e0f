"""Orientation: up and front given or detected per mesh, and the automatic GCs' names follow
them (a y-up creature facing +z gets its front-left leg named front left)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from ngc_gen.data.autogc.auto import AutoGCSettings
from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.orient import detect_orientation, parse_axis
from ngc_gen.data.autogc.skeleton_gcs import skeleton_gcs
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.sampling import gc_membership, sample_surface
from ngc_gen.geometry import GeneralizedCylinder

pytestmark = pytest.mark.usefixtures("single_thread")
# the creatures' frame (+x front, +z up) -> y up, facing +z (then +x is the left)
Y_UP = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
LEGS = {"leg_fl": "leg_front_left", "leg_fr": "leg_front_right", "leg_bl": "leg_back_left",
        "leg_br": "leg_back_right"}


@pytest.fixture(scope="module")
def creature():
    from ngc_gen.data.procedural.creatures import make_creature

    mesh, ann = make_creature(3, resolution=64, check_samples=0)
    true = [GeneralizedCylinder.from_dict(g) for g in ann["gcs"]]
    points, _ = sample_surface(mesh.vertices, mesh.faces, 20_000, np.random.default_rng(0))
    return mesh, true, points


def _args(**kw) -> dict:
    """skeleton_gcs's arguments: conf/annotate/default.yaml's, `kw` replacing some."""
    d = dataclasses.asdict(AutoGCSettings.from_yaml(**kw))
    d.pop("method")
    return d


def _leg_names(creature, rotation, **kw) -> dict[str, str]:
    """true leg -> the name of the automatic GC holding most of its samples."""
    mesh, true, points = creature
    turned = trimesh.Trimesh(mesh.vertices @ rotation.T, mesh.faces, process=False)
    gcs, info = skeleton_gcs(turned, **_args(resolution=64, samples=8000, **kw))
    part = rho_matrix(true, points)[0].argmin(axis=0)
    pp, pg, _ = gc_membership(points @ rotation.T, gcs)
    inside = np.zeros((len(points), len(gcs)), dtype=bool)
    inside[pp, pg] = True
    names = [g.name for g in true]
    return {leg: gcs[int(inside[part == names.index(leg)].mean(0).argmax())].name
            for leg in LEGS}, info


def test_a_y_up_creature_facing_z_gets_its_legs_named_by_its_own_front_and_left(creature):
    got, info = _leg_names(creature, Y_UP)
    assert info["orientation"].describe() == "up +y (detected), front +z (detected)"
    assert got == LEGS
    given, info = _leg_names(creature, Y_UP, up="+y", front="+z")
    assert given == LEGS and info["orientation"].source == ("given", "given")
    # read in the world's axes instead (the old behaviour), the same legs get other names
    wrong, _ = _leg_names(creature, Y_UP, up="+z", front="+x")
    assert wrong != LEGS


def test_detection_from_parts_legs_down_head_high():
    """Synthetic parts in a y-up, +z-front frame: a trunk along z, four legs down, a neck up
    at +z, a tail back; the surface's front end is higher."""
    trunk = np.linspace([0, 0, -0.5], [0, 0, 0.5], 9)
    legs = [np.linspace([x, 0, z], [x, -0.6, z], 5) for x in (-0.1, 0.1) for z in (-0.4, 0.4)]
    neck = np.linspace([0, 0, 0.5], [0, 0.4, 0.7], 5)
    tail = np.linspace([0, 0, -0.5], [0, -0.2, -0.8], 5)
    curves = [trunk, *legs, neck, tail]
    points = np.concatenate(curves)
    o = detect_orientation(curves, [1.0, 0.1, 0.1, 0.1, 0.1, 0.2, 0.05], None, None, None, points)
    assert np.allclose(o.up, [0, 1, 0]) and np.allclose(o.front, [0, 0, 1])
    assert np.allclose(o.left, [1, 0, 0]) and o.source == ("detected", "detected")
    # a flat star has no up: the default, said so
    flat = [np.linspace([0, 0, 0], [0.8, 0, 0], 5), np.linspace([0, 0, 0], [-0.4, 0.6, 0], 5),
            np.linspace([0, 0, 0], [-0.4, -0.6, 0], 5)]
    o = detect_orientation(flat, [1.0, 0.5, 0.5], None, None, None, np.concatenate(flat))
    assert o.source[0] == "default" and np.allclose(o.up, [0, 0, 1])


def test_given_axes_are_read_and_bad_ones_refused():
    assert np.allclose(parse_axis("+y", "annotate.up"), [0, 1, 0])
    assert np.allclose(parse_axis("-z", "annotate.up"), [0, 0, -1])
    assert np.allclose(parse_axis([0, 2, 0], "annotate.up"), [0, 1, 0])
    assert parse_axis("auto", "annotate.up") is None
    with pytest.raises(DataError, match="annotate.front"):
        AutoGCSettings.from_yaml(front="sideways")
