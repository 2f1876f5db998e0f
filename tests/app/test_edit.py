"""edit.py as a user runs it: bad programs fail before any output, good ones write everything."""
import json

import pytest
import yaml

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.procedural.creatures import CREATURE_PARTS
from ngc_gen.edit.program import EditProgram
from ngc_gen.edit import EditError
from ngc_gen.app.stages.edit_shapes import run_edit
from ngc_gen.app.runtime.programs import available_programs

from ..edit.conftest import make_module, save_checkpoint
from ..helpers import ROOT, compose_config, run_entry


@pytest.fixture(scope="module")
def ckpt(tmp_path_factory):
    path = tmp_path_factory.mktemp("run") / "last.ckpt"
    save_checkpoint(make_module(), path)
    return path


def edit(ckpt, out, *args):
    """edit.py run from out's parent folder, so any stray file would show up there."""
    return run_entry("edit.py", f"run={ckpt}", f"out_dir={out}", "extract.resolution=40", *args,
                     cwd=out.parent, timeout=300)


def write_program(tmp_path, ops, name="bad.yaml", **top):
    prog = tmp_path / name
    prog.write_text(yaml.safe_dump({"name": "p", "shape": "one", "ops": ops, **top}))
    return prog


@pytest.mark.parametrize("ops, match", [
    ([{"op": "twist", "gc": "body", "t": 0.5, "degrees": 10},
      {"op": "twist", "gc": "wing", "t": 0.5, "degrees": 10}], r"ops\[1\].*GC 'wing'"),
    ([{"op": "scale", "gc": "arm", "t": 0.5, "factor": 0}], r"ops\[0\].*factor = 0"),
    ([{"op": "twist", "gc": "arm", "t": 1.5, "degrees": 10}], r"ops\[0\].*t = 1.5"),
    ([{"op": "curl", "gc": "arm"}], r"ops\[0\].*unknown op"),
    ([{"op": "stretch", "gc": "arm", "t0": 0.1}], r"ops\[0\].*missing.*factor"),
    ([{"op": "twist", "gc": "arm", "t": 0.5, "degrees": 10},
      {"op": "mix", "gc": "arm", "source": {"shape": "three"}}], r"ops\[1\].*unknown shape"),
])
def test_bad_programs_fail_before_any_output(tmp_path, ckpt, ops, match):
    """In process (fast): run_edit raises EditError naming file, op, GC, field; no output."""
    prog = write_program(tmp_path, ops)
    out = tmp_path / "out"
    cfg = compose_config("edit", [f"run={ckpt}", f"out_dir={out}", "extract.resolution=32",
                                  f"program_file={prog}"])
    with pytest.raises(EditError, match=match) as e:
        run_edit(cfg)
    assert str(e.value).startswith(f"program {prog}")
    assert not out.exists()


def test_bad_program_exits_2_with_one_line_and_no_output(tmp_path, ckpt):
    prog = write_program(tmp_path, [{"op": "twist", "gc": "arm", "t": 0.5, "degrees": 10},
                                    {"op": "scale", "gc": "wing", "t": 0.5, "factor": 2}])
    out = tmp_path / "out"
    r = edit(ckpt, out, f"program_file={prog}")
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"error: program {prog}, ops[1]: edit 'scale' on GC 'wing'")
    assert "Traceback" not in r.stderr and not out.exists()
    assert list(tmp_path.iterdir()) == [prog]  # and nothing else anywhere (no Hydra folders)


def test_shipped_program_on_a_checkpoint_without_its_shape_is_a_clear_error(tmp_path, ckpt):
    out = tmp_path / "out"
    cfg = compose_config("edit", [f"run={ckpt}", f"out_dir={out}", "edit=bent_tail"])
    with pytest.raises(EditError, match="unknown shape.*'one', 'two'.*Fix: pass shape=<name>"):
        run_edit(cfg)
    assert not out.exists()


def test_a_program_writes_meshes_gcs_and_metrics(tmp_path, ckpt):
    prog = tmp_path / "good.yaml"
    prog.write_text(yaml.safe_dump({"name": "good", "ops": [
        {"op": "twist_ramp", "gc": "body", "t0": 0.0, "t1": 1.0, "degrees": 60},
        {"op": "handles", "gc": "arm", "fixed": ["body"],
         "rotate": {"axis": [0, 1, 0], "degrees": 30}},
        {"op": "mix", "gc": "tail", "source": {"shape": "two"}, "blend": "smoothstep",
         "t0": 0.2, "t1": 0.8}]}))
    out = tmp_path / "out"
    r = edit(ckpt, out, f"program_file={prog}", "shape=one")
    assert r.returncode == 0, r.stderr
    assert {p.name for p in out.iterdir()} == {"undeformed.ply", "deformed.ply", "edited.yaml",
                                              "program.yaml", "metrics.json", "edit.png"}
    m = json.loads((out / "metrics.json").read_text())
    assert m["picture"] == str(out / "edit.png")
    assert m["shape"] == "one" and 0 <= m["eps_v"] < 0.2 and m["mixes"] == {"tail": "two/tail"}
    assert [o["op"] for o in m["ops"]] == ["twist_ramp", "handles", "mix"]
    ann = load_annotation(out / "edited.yaml")  # loadable again, mesh = the deformed mesh
    assert ann.gc_names == ["body", "arm", "tail"] and ann.mesh_path == out / "deformed.ply"
    assert ann.gcs[0].keys[-1].twist == pytest.approx(20.0 + 60.0)
    assert yaml.safe_load((out / "program.yaml").read_text())["shape"] == "one"


def test_shipped_programs_are_well_formed():
    """Every conf/edit program composes through Hydra, passes the structure check and names
    GCs of its shape's template (creatures; the ant's annotation)."""
    ant = ROOT / "datasets" / "ant" / "ant.yaml"
    ant_gcs = load_annotation(ant).gc_names if ant.exists() else None
    names = available_programs()
    assert {"bent_tail", "twisted_leg", "scaled_head", "stretched_torso", "posed_ant_leg",
            "head_swap"} <= set(names)
    for name in names:
        cfg = compose_config("edit", [f"edit={name}", "run=x"])
        from omegaconf import OmegaConf

        prog = EditProgram.from_dict(OmegaConf.to_container(cfg.edit), source=name)
        template = ant_gcs if prog.shape == "ant" else list(CREATURE_PARTS)
        if template is None:
            continue
        for op in prog.ops:
            for key in ("gc", "carry", "fixed"):
                v = op.get(key)
                for g in ([v] if isinstance(v, str) else v or []):
                    assert g == "all" or g in template, (name, key, g)


def test_edited_yaml_prepares_again_in_its_own_frame(tmp_path, ckpt):
    """edited.yaml (normalize: false) + deformed.ply can be prepared for a refit as they are:
    the mesh is not re-normalised, so the edited GCs still hold it. (This untrained decoder's
    surface runs along its GC boundaries, which a 40^3 grid rounds outwards by up to a cell;
    fitted shapes reach 99.7-99.9%, see conf/edit.yaml.)"""
    import numpy as np
    import trimesh

    from ngc_gen.data.prepare import PrepareSettings, prepare_shape

    prog = write_program(tmp_path, [{"op": "twist", "gc": "arm", "t": 0.5, "degrees": 40}],
                         name="good.yaml")
    out = tmp_path / "out"
    run_edit(compose_config("edit", [f"run={ckpt}", f"out_dir={out}", "extract.resolution=40",
                                     f"program_file={prog}", "picture=false"]))
    assert "normalize: false" in (out / "edited.yaml").read_text()
    ann = load_annotation(out / "edited.yaml")
    assert ann.bound is None and ann.to_dict()["normalize"] is False
    prepared = prepare_shape(ann, PrepareSettings.from_yaml(n_samples=2000, coverage_samples=4000,
                                                  min_coverage=0.9))
    deformed = trimesh.load(out / "deformed.ply", process=False)
    np.testing.assert_allclose(prepared.mesh_vertices, deformed.vertices, atol=1e-6)
