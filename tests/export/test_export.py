"""`sample.py mode=export`: the written GLB passes Khronos glTF-Validator with 0 errors (a fit,
an edit program as a clip, a rig clip carried by template names, automatic GCs), its skeleton and
skin are what the GCs say, the corrective morph targets put the played-back pose on NGC's posed
surface, and a rig's clip turns the joints of the GCs it names."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from ngc_gen.app.stages.sample import run_sample
from ngc_gen.export import (ExportSettings, GLBContent, Playback, build_skeleton,
                            joint_matrices, write_glb)
from ngc_gen.export.validator import validate, validator_available
from ngc_gen.shape import load_shapes

from .conftest import export_config

pytestmark = pytest.mark.usefixtures("single_thread")
needs_validator = pytest.mark.skipif(not validator_available(),
                                     reason="gltf-validator not installed (make gltf-validator)")

BEND = {"name": "bend_arm", "description": "the arm bent", "ops": [
    {"op": "bend", "gc": "arm", "indices": [2], "offsets": [[0.25, 0.0, -0.15]]}]}


def _assert_valid(path):
    if validator_available():
        report = validate(path)
        assert report["errors"] == 0, report["messages"]


def test_fit_rest_pose(fit_ckpt, tmp_path):
    out = tmp_path / "one.glb"
    summary = run_sample(export_config(fit_ckpt, out, "shape=one", "export.picture=true"))
    _assert_valid(out)
    assert out.with_suffix(".png").stat().st_size > 0  # the rest pose with its joints
    p = Playback(out)
    assert p.joint_names == [f"{g}_{k}" for g in ("body", "arm", "tail") for k in range(3)]
    assert summary["joints"] == 9 and summary["keyframes"] == 0
    w = p.rig.skin_weights
    assert np.allclose(w.sum(1), 1.0, atol=1e-6) and (w > 0).sum(1).max() <= 4
    # the arm's vertices near its tip are skinned to the arm's last joint
    shape = load_shapes(fit_ckpt)["one"]
    tip = shape.gcs[1].curve.points[-1]
    near = np.linalg.norm(p.vertices() - tip, axis=1).argmin()
    dominant = p.rig.skin_joints[near, p.rig.skin_weights[near].argmax()]
    assert p.joint_names[dominant] == "arm_2"
    # the bind pose is the shape's GC frames: joint k at t = k / 3 of its curve
    assert np.allclose(p.joint_positions()[3], shape.gcs[1].curve.points[0], atol=1e-5)


@pytest.mark.parametrize("correctives", [True, False])
def test_edit_program_clip(fit_ckpt, tmp_path, correctives):
    program = tmp_path / "bend.yaml"
    program.write_text(yaml.safe_dump(BEND))
    out = tmp_path / "bend.glb"
    run_sample(export_config(fit_ckpt, out, "shape=one", f"clip=edit:{program}",
                             f"export.correctives={str(correctives).lower()}"))
    _assert_valid(out)
    p = Playback(out)
    assert list(p.keyframes) == [0.0, 1.0]
    assert (p.targets is not None) == correctives
    from ngc_gen.edit.program import EditProgram

    posed = load_shapes(fit_ckpt)["one"].edited(EditProgram.from_dict(BEND))
    err = np.abs(posed.sdf(p.vertices(1.0)).numpy())
    if correctives:  # on NGC's posed zero set (skinning alone is not)
        plain = np.abs(posed.sdf(p.vertices(1.0, morph=False)).numpy())
        assert np.median(err) < 0.2 * np.median(plain)
        assert np.median(err) < 1e-3
    # the arm's last joint went where the edited GC's frame is
    world = joint_matrices(build_skeleton(posed.gcs, 3), posed.gcs)
    assert np.allclose(p.joint_positions(1.0), world[:, :3, 3], atol=1e-4)


def test_in_between_keys_keep_the_slerp():
    """In-between joint keys lie on glTF's slerp between the keyframes (so the clip plays the
    same), and no joint turns more than the limit between two keys."""
    from ngc_gen.data.rigs.rig import slerp
    from ngc_gen.export.glb_writer import in_between_keys

    rng = np.random.default_rng(0)
    R = rng.normal(size=(3, 4, 4))
    R /= np.linalg.norm(R, axis=-1, keepdims=True)
    for k in (1, 2):  # the shorter arcs, as the writer hands them over
        R[k] *= np.where((R[k] * R[k - 1]).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    T = rng.normal(size=(3, 4, 3))
    times, t, q = in_between_keys(np.array([0.0, 1.0, 3.0]), T, R, 10.0)
    assert times[0] == 0.0 and times[-1] == 3.0 and len(times) > 10
    turn = np.degrees(2 * np.arccos(np.clip(np.abs((q[1:] * q[:-1]).sum(-1)), 0, 1)))
    assert turn.max() <= 10.0 + 1e-9
    for i, tm in enumerate(times):
        seg = 0 if tm < 1.0 else 1
        f = (tm - [0.0, 1.0][seg]) / [1.0, 2.0][seg]
        want = np.stack([slerp(R[seg, j], R[seg + 1, j], f) for j in range(4)])
        assert np.allclose(q[i], want, atol=1e-9)
        assert np.allclose(t[i], (1 - f) * T[seg] + f * T[seg + 1])


def _mini_rig(path, degrees):
    """A rig GLB (written by the exporter itself) whose leg turns `degrees` about x over 1 s:
    Spine (root) -> Leg1 -> Leg2, Spine -> Tail1."""
    names = ["Spine", "Leg1", "Leg2", "Tail1"]
    parent = np.array([-1, 0, 1, 0])
    rest = np.tile(np.eye(4), (4, 1, 1))
    rest[:, :3, 3] = [[0, 0, 0], [0.3, 0, 0], [0.3, -0.3, 0], [-0.4, 0, 0]]
    a = np.radians(degrees)
    turn = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    posed = rest.copy()
    posed[1, :3, :3] = turn
    posed[2, :3, :3] = turn
    posed[2, :3, 3] = rest[1, :3, 3] + turn @ (rest[2, :3, 3] - rest[1, :3, 3])
    tri = np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], float)
    write_glb(path, GLBContent(tri, np.array([[0, 1, 2]]), np.tile([0, 0, 1.0], (3, 1)), names,
                               parent, rest, np.zeros((3, 4), int),
                               np.tile([1.0, 0, 0, 0], (3, 1)), clip_name="Swing",
                               times=np.array([0.0, 1.0]), world=np.stack([rest, posed])))
    template = {"version": 1, "name": "mini", "gcs": [
        {"name": "torso", "joints": ["Spine"], "degree": 2, "keys": [0.0, 1.0],
         "up": [0, 1, 0], "extend": [False, False], "parent": None},
        {"name": "leg_fl", "joints": ["Leg1", "Leg2"], "degree": 2, "keys": [0.0, 1.0],
         "up": [1, 0, 0], "extend": [False, False], "parent": "torso"},
        {"name": "neck", "joints": ["Tail1"], "degree": 2, "keys": [0.0, 1.0],
         "up": [0, 1, 0], "extend": [False, False], "parent": "torso"}]}
    return template


def test_rig_clip_by_template_names(animal_ckpt, tmp_path):
    rig = tmp_path / "mini.glb"
    tpl = tmp_path / "mini.yaml"
    tpl.write_text(yaml.safe_dump(_mini_rig(rig, 40.0)))
    out = tmp_path / "animal.glb"
    run_sample(export_config(animal_ckpt, out, f"clip=rig:{rig}/Swing", f"export.template={tpl}",
                             "export.frames=3"))
    _assert_valid(out)
    p = Playback(out)
    assert len(p.keyframes) == 3 and p.targets.shape[0] == 3
    w0 = p.rig.world_matrices(p.clip, 0.0)[p.rig.joints]
    w1 = p.rig.world_matrices(p.clip, p.times[-1])[p.rig.joints]
    names = p.joint_names
    delta = w1[:, :3, :3] @ np.swapaxes(w0[:, :3, :3], 1, 2)
    angle = np.degrees(np.arccos(np.clip((np.trace(delta, axis1=1, axis2=2) - 1) / 2, -1, 1)))
    leg = [i for i, n in enumerate(names) if n.startswith("leg_fl")]
    still = [i for i, n in enumerate(names) if n.startswith(("torso", "tail"))]
    assert np.allclose(angle[leg], 40.0, atol=0.5)  # the leg turns as the source's leg
    assert np.allclose(angle[still], 0.0, atol=1e-3)  # the tail: not in the source, stays


@needs_validator
def test_automatic_gcs(auto_ckpt, tmp_path):
    out = tmp_path / "auto.glb"
    summary = run_sample(export_config(auto_ckpt, out, "export.colors=true"))
    assert validate(out)["errors"] == 0
    p = Playback(out)
    assert summary["joints"] == 3 * 3 and (p.rig.joint_parent() < 0).sum() == 1


def test_settings_match_the_config():
    """The library's settings fields are the config's (conf/mode/export.yaml)."""
    cfg = export_config("x", __import__("pathlib").Path("/tmp/x.glb"))
    fields = set(ExportSettings.__dataclass_fields__)
    assert fields <= set(cfg.export)
