"""The editor's state machine through its Python API (no browser): each interaction changes the
GCs as the user asked, undo/redo round-trip, bad interactions are refused with a message and
leave the shape as it was, and a saved program replays with edit.py to the same mesh."""
import re
import shlex

import numpy as np
import pytest
import torch
import trimesh
import yaml

from ngc_gen.app.editor.start import open_session
from ngc_gen.data.errors import DataError
from ngc_gen.edit import EditProgram
from ngc_gen.app.stages.edit_shapes import run_edit
from ngc_gen.shape.mixing import start_frame

from .conftest import RES, editor_config, mesh_chamfer
from ...helpers import compose_config

pytestmark = pytest.mark.usefixtures("single_thread")


def gc(session, name):
    return session.shape.gcs[session.shape.index(name)]


def dicts(shape):
    return [g.to_dict() for g in shape.gcs]


def test_move_point_follows_the_drag_and_one_drag_is_one_op(session):
    p = gc(session, "arm").curve.points[2].copy()
    for step in (0.02, 0.05, 0.08):  # one drag: three updates of the same point
        target = p + np.array([0.0, step, -step])
        assert session.move_point("arm", 2, target)
    np.testing.assert_allclose(gc(session, "arm").curve.points[2], target, atol=1e-12)
    np.testing.assert_array_equal(gc(session, "body").curve.points,
                                  session.base.gcs[0].curve.points)
    assert [o["op"] for o in session.ops] == ["move"]
    np.testing.assert_allclose(session.ops[0]["offsets"], [[0.0, 0.08, -0.08]], atol=1e-12)
    assert session.move_point("arm", 1, gc(session, "arm").curve.points[1] + 0.01)
    assert len(session.ops) == 2  # another point: another op


def test_key_sliders_set_radius_and_twist(session):
    assert session.set_radius("arm", 0, 0.1)
    assert session.set_radius("arm", 0, 0.12)  # the same slider again: one op
    k = gc(session, "arm").keys[0]
    assert 0.5 * (k.radii[0] + k.radii[1]) == pytest.approx(0.12, abs=1e-12)
    assert k.radii[0] / k.radii[1] == pytest.approx(0.09 / 0.07)  # aspect kept
    assert session.set_twist("body", 1, 45.0)
    assert gc(session, "body").keys[1].twist == pytest.approx(45.0)
    assert gc(session, "body").keys[0].twist == 0.0
    assert [(o["op"], o["t"]) for o in session.ops] == [("scale", 0.0), ("twist", 1.0)]


def test_stretch_lengthens_the_range(session):
    L = gc(session, "body").length
    assert session.stretch("body", 0.25, 0.75, 1.5)
    assert gc(session, "body").length == pytest.approx(L * 1.25, rel=1e-3)
    assert session.ops[-1] == {"op": "stretch", "gc": "body", "t0": 0.25, "t1": 0.75,
                               "factor": 1.5}


def test_pose_turns_the_far_end_about_the_start(session):
    before = gc(session, "arm")
    start, end = before.curve.points[0], before.curve.points[-1]
    axis = start_frame(before)[2]
    assert session.pose("arm", "normal", 30.0)
    after = gc(session, "arm")
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(axis * np.radians(30.0)).as_matrix()
    np.testing.assert_allclose(after.curve.points[0], start, atol=1e-9)
    np.testing.assert_allclose(after.curve.points[-1], start + R @ (end - start), atol=1e-6)
    assert after.length == pytest.approx(before.length, rel=1e-6)  # handles keep arc length
    assert session.ops[-1]["fixed"] == ["body"]  # the GC the limb grows from stays


def test_mix_takes_the_source_part(session):
    assert session.mix("tail", "two", blend="truncated_linear", t0=0.2, t1=0.8)
    j = session.shape.index("tail")
    two = session.library["two"]
    assert torch.equal(session.shape.mixes[j].code, two.codes[j])
    assert session.shape.mixes[j].label == "two/tail"
    assert session.mix("tail", "two", blend="replace")  # same GC again: updates the op
    assert len(session.ops) == 1 and session.ops[0]["blend"] == "replace"


def test_undo_redo_round_trip(session):
    base = dicts(session.base)
    p = gc(session, "tail").curve.points[1]
    session.move_point("tail", 1, p + 0.03)
    session.move_point("tail", 1, p + 0.05)  # the same drag
    session.set_twist("arm", 1, 30.0)
    session.stretch("body", 0.0, 0.5, 1.2)
    edited, ops = dicts(session.shape), session.ops
    assert len(ops) == 3
    for _ in range(3):
        assert session.undo()
    assert session.ops == [] and dicts(session.shape) == base
    assert not session.undo()
    for _ in range(3):
        assert session.redo()
    assert session.ops == ops and dicts(session.shape) == edited
    assert not session.redo()
    session.undo()
    session.set_radius("arm", 1, 0.05)  # a new interaction drops the redo branch
    assert not session.can_redo and [o["op"] for o in session.ops] == ["move", "twist", "scale"]


def far_point(session):
    return gc(session, "arm").curve.points[1] + 1e-4  # onto its neighbour


@pytest.mark.parametrize("act, match", [
    (lambda s: s.set_radius("arm", 0, 0.0), r"factor = 0.*must be positive"),
    (lambda s: s.set_radius("arm", 0, 1e-4),
     r"radius 8.75e-05 at key t = 0 is below the editor's minimum"),
    (lambda s: s.move_point("arm", 2, far_point(s)), r"control points 1 and 2 .* closer than"),
    (lambda s: s.move_point("arm", 2, [3.0, 0.0, 0.0]), r"leaves the extraction box"),
    (lambda s: s.set_twist("body", 1, 10000.0), r"twist 10000.0 deg .* exceeds"),
    (lambda s: s.mix("tail", "three"), r"unknown shape"),
    (lambda s: s.mix("tail", "two", source_gc="wing"), r"no GC named so"),
    (lambda s: s.mix("tail", "two", blend="truncated_linear", t0=0.8, t1=0.2), r"t0 < t1"),
    (lambda s: s.stretch("body", 0.7, 0.3, 2.0), r"empty"),
    (lambda s: s.set_twist("wing", 0, 10.0), r"no GC named 'wing'"),
    (lambda s: s.set_radius("arm", 7, 0.1), r"keys 0..1, not 7"),
])
def test_bad_interactions_are_refused_and_keep_the_shape(session, act, match):
    session.set_twist("body", 0, 5.0)  # a valid op before, so "kept" is not just the base
    shape, ops, version = session.shape, session.ops, session.version
    out = act(session)
    assert not out and out.message.startswith("refused: ")
    assert re.search(match, out.message), out.message
    assert session.message == out.message
    assert session.shape is shape and session.ops == ops and session.version == version


def test_refused_update_of_a_drag_keeps_its_last_valid_value(session):
    assert session.set_radius("arm", 0, 0.1)
    assert not session.set_radius("arm", 0, 0.0)
    assert session.set_radius("arm", 0, 0.11)  # the drag goes on from where it was valid
    assert len(session.ops) == 1
    k = gc(session, "arm").keys[0]
    assert 0.5 * (k.radii[0] + k.radii[1]) == pytest.approx(0.11)


def test_mixing_a_gc_twice_is_refused(session):
    assert session.mix("tail", "two")
    assert session.set_twist("arm", 0, 10.0)
    out = session.mix("tail", "two", blend="linear")
    assert not out and "already mixed" in out.message


def out_of(mixes):
    return {j: (m.label, m.code.tolist(), repr(m.weight)) for j, m in mixes.items()}


def replay(tmp_path, ckpt, program):
    """Run the replay command the program's header names (as a user would paste it)."""
    out = tmp_path / "replay"
    head = "# Replay: python edit.py "
    line = next(ln for ln in program.read_text().splitlines() if ln.startswith(head))
    args = shlex.split(line[len(head):])
    assert f"run={ckpt}" in args and f"extract.resolution={RES}" in args, line
    cfg = compose_config("edit", [*args, f"out_dir={out}", "picture=false"])
    run_edit(cfg)
    return trimesh.load(out / "deformed.ply", process=False)


def test_saved_program_replays_with_edit_py_to_the_same_mesh(session, checkpoint, tmp_path):
    p = gc(session, "tail").curve.points[2]
    assert session.move_point("tail", 2, p + np.array([0.05, 0.0, 0.08]))
    assert session.set_radius("body", 1, 0.15)
    assert session.set_twist("arm", 1, 40.0)
    assert session.stretch("body", 0.2, 0.6, 1.3)
    assert session.pose("arm", "binormal", -25.0)
    assert session.mix("tail", "two", blend="smoothstep", t0=0.1, t1=0.9)
    # interactions apply one op to the shape before it: the same as the whole program
    whole = EditProgram.from_dict(session.program()).apply_to(
        session.base, session.library.resolver(session.base))
    assert dicts(whole) == dicts(session.shape)
    assert out_of(whole.mixes) == out_of(session.shape.mixes)
    out = session.save(tmp_path / "program.yaml", RES)
    assert out and out.paths == (tmp_path / "program.yaml",)
    text = (tmp_path / "program.yaml").read_text()
    assert f"# Replay: python edit.py run={checkpoint} program_file={tmp_path}/program.yaml" \
        in text
    assert yaml.safe_load(text)["ops"] == session.ops
    mine = session.mesh(RES).mesh
    theirs = replay(tmp_path, checkpoint, tmp_path / "program.yaml")
    assert len(mine.faces) > 1000 and len(theirs.faces) == len(mine.faces)
    assert mesh_chamfer(mine, theirs) < 1e-8
    session.export_mesh(tmp_path / "mesh.ply", RES)
    exported = trimesh.load(tmp_path / "mesh.ply", process=False)
    assert mesh_chamfer(exported, theirs) < 1e-8


def test_a_shape_no_checkpoint_holds_saves_one_beside_the_program(session, checkpoint,
                                                                   tmp_path):
    one = session.library["one"]
    made = session.library.add(one.replaced(name="made", codes=one.codes * 0.5))
    assert session.open("made")
    assert session.set_twist("body", 1, 60.0)
    out = session.save(tmp_path / "p.yaml", RES)
    ckpt = tmp_path / "p.shapes.ckpt"
    assert out.paths == (ckpt, tmp_path / "p.yaml")
    assert f"run={ckpt}" in (tmp_path / "p.yaml").read_text()
    theirs = replay(tmp_path, ckpt, tmp_path / "p.yaml")
    assert mesh_chamfer(session.mesh(RES).mesh, theirs) < 1e-8
    assert made.name == "made"


def test_save_without_ops_and_open_errors(session, checkpoint, tmp_path):
    out = session.save(tmp_path / "p.yaml", RES)
    assert not out and "no ops" in out.message and not (tmp_path / "p.yaml").exists()
    with pytest.raises(DataError, match="no shape named 'three'"):
        open_session(editor_config(checkpoint, "shape=three"))
    with pytest.raises(DataError, match="no run given"):
        open_session(compose_config("edit", ["viewer=true"]))


def test_a_starting_program_is_the_first_document(checkpoint, tmp_path):
    prog = tmp_path / "start.yaml"
    prog.write_text(yaml.safe_dump({"name": "start", "shape": "two", "ops": [
        {"op": "twist", "gc": "arm", "t": 1.0, "degrees": 15.0}]}))
    session, latent = open_session(editor_config(checkpoint, f"program_file={prog}"))
    assert latent is None and session.base.name == "two" and session.name == "start"
    assert session.shape.gcs[1].keys[1].twist == pytest.approx(15.0)
    assert session.undo().ok is False  # the starting program is not an interaction
