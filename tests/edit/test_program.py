"""Edit programs: structure checks, value checks through the ops, and what each op does."""
import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.edit import EditError
from ngc_gen.edit.program import EditProgram, MixSource, apply_program, handle_points, region_mask

SRC = "conf/edit/test.yaml"


def program(*ops, **top):
    return EditProgram.from_dict({"name": "t", "ops": list(ops), **top}, source=SRC)


def run(gcs, *ops, resolve=None):
    return apply_program(program(*ops), gcs, resolve)


def tip(gc, u=1.0):
    return gc.to_world(np.array([[u, 0.0, 0.0]]))[0]


# ---- structure -------------------------------------------------------------------------------
@pytest.mark.parametrize("d, match", [
    ({"ops": []}, "non-empty list"),
    ({"ops": [{"op": "bendd", "gc": "arm"}]}, r"ops\[0\]: op = 'bendd': unknown op"),
    ({"ops": [{"op": "twist", "gc": "arm", "t": 1.0}]}, r"ops\[0\].*missing.*degrees"),
    ({"ops": [{"op": "scale", "gc": "arm", "t": 1.0, "factor": 2, "fallof": 0.1}]},
     r"unknown field.*fallof"),
    ({"ops": [{"gc": "arm"}]}, "'op' name"),
    ({"ops": [{"op": "twist", "gc": "arm", "t": 0, "degrees": 1}], "smoothunion": 1},
     "unknown program keys"),
    ({"ops": [{"op": "twist", "gc": "arm", "t": 0, "degrees": 1}], "smooth_union": -1},
     "smooth_union"),
])
def test_structure_errors_name_the_program_and_op(d, match):
    with pytest.raises(EditError, match=match) as e:
        EditProgram.from_dict(d, source=SRC)
    assert SRC in str(e.value)


@pytest.mark.parametrize("op, match", [
    ({"op": "twist", "gc": "leg", "t": 0.5, "degrees": 10}, r"GC 'leg'.*unknown GC"),
    ({"op": "twist", "gc": "arm", "t": 1.3, "degrees": 10}, r"GC 'arm'.*t = 1.3.*\[0, 1\]"),
    ({"op": "scale", "gc": "arm", "t": 0.5, "factor": 0}, r"GC 'arm'.*factor = 0.*positive"),
    ({"op": "stretch", "gc": "body", "t0": 0.5, "t1": 0.2, "factor": 2}, "empty"),
    ({"op": "rotate", "gc": ["arm", "tail"], "axis": [0, 0, 0], "degrees": 3}, "nonzero"),
    ({"op": "handles", "gc": "arm", "at": [0.9, 1.2]}, r"at\[1\] = 1.2"),
    ({"op": "mix", "gc": "arm", "source": {"shape": "two"}, "blend": "wobbly"}, "unknown blend"),
])
def test_value_errors_name_program_op_index_gc_and_field(gcs, op, match):
    ok = {"op": "twist", "gc": "body", "t": 0.5, "degrees": 5}
    with pytest.raises(EditError, match=match) as e:
        run(gcs, ok, op, resolve=lambda *a: None)
    assert f"program {SRC}, ops[1]" in str(e.value)
    assert e.value.index == 1 and e.value.program == SRC


def test_program_leaves_input_gcs_alone(gcs):
    before = [g.to_dict() for g in gcs]
    res = run(gcs, {"op": "twist", "gc": "all", "t": None, "degrees": 30},
              {"op": "scale", "gc": ["arm", "tail"], "t": 0.5, "factor": 1.2})
    assert [g.to_dict() for g in gcs] == before
    assert [g.name for g in res.gcs] == [g.name for g in gcs]
    assert res.log[0]["gcs"] == ["body", "arm", "tail"]


# ---- ops -------------------------------------------------------------------------------------
def test_carry_moves_attached_parts_with_a_stretch(gcs):
    body, arm = gcs[0], gcs[1]
    res = run(gcs, {"op": "stretch", "gc": "body", "t0": 0.2, "t1": 0.5, "factor": 1.5,
                    "carry": ["arm"]})
    new_body, new_arm = res.gcs[0], res.gcs[1]
    # the arm's start keeps its relative coordinates in the body; the arm keeps its shape
    p = arm.curve.points[0]
    q = new_body.to_world(body.to_relative(p[None]))[0]
    np.testing.assert_allclose(new_arm.curve.points[0], q, atol=1e-6)
    assert new_arm.length == pytest.approx(arm.length, rel=1e-9)
    assert res.gcs[2] is gcs[2]  # not carried: unchanged


def test_rotate_a_list_of_gcs_about_the_first_start(gcs):
    res = run(gcs, {"op": "rotate", "gc": ["arm", "tail"], "axis": [0, 0, 1], "degrees": 90})
    R = Rotation.from_rotvec([0, 0, np.pi / 2]).as_matrix()
    p = gcs[1].curve.points[0]
    for old, new in zip(gcs[1:], res.gcs[1:]):
        np.testing.assert_allclose(new.curve.points, (old.curve.points - p) @ R.T + p, atol=1e-12)


def test_handles_op_drags_the_end_and_keeps_length(gcs):
    arm = gcs[1]
    res = run(gcs, {"op": "handles", "gc": "arm", "at": [0.9, 1.0], "fixed": ["body"],
                    "rotate": {"axis": [0, 1, 0], "degrees": 40}})
    new = res.gcs[1]
    R = Rotation.from_rotvec([0, np.radians(40), 0]).as_matrix()
    p = arm.curve.points[0]
    H = handle_points(arm, (1.0, 1.0))  # the end cross-section moves rigidly (handles.py)
    moved = new.to_world(arm.to_relative(H))
    np.testing.assert_allclose(moved, (H - p) @ R.T + p, atol=1e-3)
    assert new.length == pytest.approx(arm.length, rel=1e-3)
    assert res.log[0]["gcs"] == ["arm"] and res.gcs[0] is gcs[0]


def test_region_mask_selects_the_end_of_a_gc(gcs):
    arm = gcs[1]
    pts = arm.to_world(np.array([[0.95, 0.2, 0.1], [1.5, 0.1, 0], [0.0, 0.1, 0], [0.9, 1.5, 0]]))
    np.testing.assert_array_equal(region_mask(arm, pts, (0.9, 1.0)), [True, True, False, False])


def resolver(gcs, codes=None):
    codes = codes if codes is not None else torch.arange(3 * 4, dtype=torch.float32).view(3, 4)
    names = [g.name for g in gcs]

    def resolve(shape, gc, ckpt):
        if gc not in names:
            raise EditError("no such source GC", field="source.gc", value=gc)
        return MixSource(codes[names.index(gc)], gcs[names.index(gc)], f"{shape}/{gc}")
    return resolve


def test_mix_plans_features_and_can_take_the_source_geometry(gcs):
    res = run(gcs, {"op": "mix", "gc": "tail", "source": {"shape": "two", "gc": "arm"},
                    "geometry": "source"},
              {"op": "mix", "gc": "arm", "source": "two", "blend": "truncated_linear",
               "t0": 0.2, "t1": 0.8, "geometry": "target"}, resolve=resolver(gcs))
    assert set(res.mixes) == {"tail", "arm"} and res.mixes["tail"].label == "two/arm"
    new_tail = res.gcs[2]
    assert new_tail.name == "tail" and new_tail.length == pytest.approx(gcs[1].length)
    # the source GC sits on the target's start frame
    s = torch.zeros(1, dtype=torch.float64)
    for a, b in zip(new_tail.frame(s, s), gcs[2].frame(s, s)):
        np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-9)
    assert res.gcs[1] is gcs[1]  # geometry: target keeps the GC


def test_mix_takes_the_source_geometry_by_default(gcs):
    res = run(gcs, {"op": "mix", "gc": "tail", "source": {"shape": "two", "gc": "arm"}},
              resolve=resolver(gcs))
    assert res.gcs[2].name == "tail" and res.gcs[2].length == pytest.approx(gcs[1].length)
    assert res.mixes["tail"].weight is None  # blend: replace by default


@pytest.mark.parametrize("op, match", [
    ({"op": "mix", "gc": "arm", "source": "two", "blend": "replace", "t0": 0.2}, "takes no"),
    ({"op": "mix", "gc": "arm", "source": "two", "blend": "smoothstep"}, r"missing \['t0', 't1'\]"),
    ({"op": "mix", "gc": "arm", "source": {"gc": "wing"}}, r"source.gc = 'wing'"),
    ({"op": "mix", "gc": "arm", "source": "two", "geometry": "both"}, "geometry"),
])
def test_mix_errors(gcs, op, match):
    with pytest.raises(EditError, match=match):
        run(gcs, op, resolve=resolver(gcs))


def test_mixing_a_gc_twice_is_an_error(gcs):
    op = {"op": "mix", "gc": "arm", "source": "two"}
    with pytest.raises(EditError, match=r"ops\[1\].*already mixed"):
        run(gcs, op, op, resolve=resolver(gcs))


def test_unanticipated_bad_values_still_name_the_op(gcs):
    # a program built without the structure check (from_dict would reject samples: "many")
    prog = EditProgram("t", [{"op": "stretch", "gc": "body", "t0": 0.2, "t1": 0.4, "factor": 2,
                              "samples": "many"}], source=SRC)
    with pytest.raises(EditError, match=r"ops\[0\]: edit 'stretch' on GC 'body': bad value"):
        apply_program(prog, gcs)
