"""The main command's pipeline (`train.py experiment=demo`): its plan links the steps, bad plans
fail before anything runs, and a tiny run of all five steps writes what each single command
writes plus summary.json and overview.png."""
import json

import numpy as np
import pytest
import trimesh

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.app.stages.pipeline import STEPS, edit_row_view, plan, run_pipeline

from ..helpers import compose_config, run_entry


def demo(*overrides):
    return compose_config(overrides=["experiment=demo", "run_dir=unused", *overrides])


def test_demo_plan_links_every_step(tmp_path):
    steps = dict(plan(demo(), tmp_path))
    assert list(steps) == ["fit", "edit", "shape_latent", "diffusion", "sample"]
    fit, edit, sl, diff, sample = steps.values()
    assert fit.stage == "fit" and fit.data.name == "demo" and fit.trainer.max_steps == 1500
    assert fit.run_dir == str(tmp_path / "fit")
    assert edit.run == str(tmp_path / "fit") and edit.extract.resolution == 160
    assert edit.edit.name == "posed_ant_leg" and edit.out_dir == str(tmp_path / "edit")
    assert sl.stage == "shape_latent" and sl.data.name == "creatures" and sl.data.split == "train"
    recipe = compose_config(overrides=["experiment=generate"])  # bench/generate.py's
    assert sl.shape_latent.max_steps == recipe.shape_latent.max_steps
    assert sl.prepare.n_samples == recipe.prepare.n_samples
    assert diff.stage == "diffusion" and diff.shape_latent_run == str(tmp_path / "shape_latent")
    assert diff.diffusion.max_steps == recipe.diffusion.max_steps
    assert sample.run == str(tmp_path / "diffusion") and sample.mode == "generate"
    assert sample.n == 16 and sample.extract.resolution == 128
    assert sample.out_dir == str(tmp_path / "sample")


def test_explicit_link_is_kept(tmp_path):
    steps = dict(plan(demo("pipeline.steps=[diffusion]",
                           'pipeline.diffusion=["shape_latent_run=/runs/sl"]'), tmp_path))
    assert steps["diffusion"].shape_latent_run == "/runs/sl"


@pytest.mark.parametrize("overrides, message", [
    (["pipeline.steps=[fit,train]"], "unknown step 'train'"),
    (["pipeline.steps=[fit,fit]"], "listed twice"),
    (["pipeline.steps=[sample]"], "reads step 'diffusion'"),
    (["pipeline.steps=[edit,fit]"], "reads step 'fit'"),
    (["pipeline.steps=[]"], "no pipeline steps"),
    (['pipeline.sample=["mode=generate","no_such_key=1"]'], "step 'sample'"),
    (['pipeline.fit=["data=no_such_dataset"]'], "step 'fit'"),
    (["pipeline.edit=[trainer]"], "list of overrides"),
])
def test_bad_plan_fails_before_anything_runs(tmp_path, overrides, message):
    run = tmp_path / "run"
    with pytest.raises(DataError, match=message):
        plan(demo(*overrides), run)
    assert not run.exists()


def test_cli_bad_plan_exits_2_without_output(tmp_path):
    run = tmp_path / "run"
    r = run_entry("train.py", "experiment=demo", "pipeline.steps=[sample]", f"hydra.run.dir={run}")
    assert r.returncode == 2 and "error:" in r.stderr and "reads step 'diffusion'" in r.stderr
    assert "Traceback" not in r.stderr
    assert not (run / "summary.json").exists() and not (run / "sample").exists()


def _q(*overrides):
    """A Hydra list of quoted overrides for the command line."""
    return "[" + ",".join(f'"{o}"' for o in overrides) + "]"


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("pipeline")
    data = [f"data.out_dir={base}/data", f"prepare.cache_dir={base}/prep",
            "prepare.n_samples=4000", "prepare.coverage_samples=4000", "batch_size=1024",
            "trainer.max_steps=30", "trainer.enable_progress_bar=false"]
    mp = pytest.MonkeyPatch()
    mp.setenv("OMP_NUM_THREADS", "1")  # tiny tensors on a shared 2-core machine
    try:
        r = run_entry(
            "train.py", "experiment=demo", f"hydra.run.dir={base}/run",
            "pipeline.fit=" + _q("data=creatures", "data.n=4", "data.limit=2", *data,
                                 "extract.resolution=24"),
            "pipeline.edit=" + _q("edit=bent_tail", "extract.resolution=24"),
            "pipeline.shape_latent=" + _q("data=creatures", "data.n=4", *data,
                                          "shape_latent.latent_dim=16", "shape_latent.preview=0"),
            "pipeline.diffusion=" + _q("trainer.max_steps=30", "diffusion.denoiser.width=32",
                                       "diffusion.denoiser.depth=1"),
            "pipeline.sample=" + _q("mode=generate", "n=2", "extract.resolution=24",
                                    "progress=false"))
    finally:
        mp.undo()
    assert r.returncode == 0, r.stderr[-3000:]
    return base / "run", r.stdout


def test_tiny_pipeline_runs_every_step(tiny_run):
    run, stdout = tiny_run
    summary = json.loads((run / "summary.json").read_text())
    assert list(summary["steps"]) == ["fit", "edit", "shape_latent", "diffusion", "sample"]
    assert set(summary["steps"]) <= set(STEPS)
    for step, s in summary["steps"].items():
        assert s["dir"] == str(run / step) and s["seconds"] > 0
    assert summary["steps"]["fit"]["cd"] > 0 and summary["steps"]["shape_latent"]["steps"] == 30
    assert summary["steps"]["edit"]["program"] == "bent_tail"
    assert summary["steps"]["sample"]["n"] == 2
    for f in ("fit/checkpoints/last.ckpt", "fit/metrics.json", "edit/deformed.ply",
              "edit/edited.yaml", "shape_latent/checkpoints/last.ckpt",
              "diffusion/checkpoints/last.ckpt", "sample/shapes.ckpt", "overview.png"):
        assert (run / f).is_file(), f
    assert "pipeline finished" in stdout


def test_tiny_pipeline_samples_come_from_its_own_runs(tiny_run):
    run, _ = tiny_run
    sample = json.loads((run / "sample/summary.json").read_text())
    assert sample["source"].startswith(str(run / "diffusion"))
    edit = json.loads((run / "edit/metrics.json").read_text())
    assert edit["checkpoint"] == str(run / "fit/checkpoints/last.ckpt")
    mesh = trimesh.load(run / "sample/sample_000.ply", process=False)
    ann = load_annotation(run / "sample/sample_000.yaml")
    assert len(mesh.faces) > 0 and len(ann.gcs) == 10


def test_overview_looks_across_the_edit(tiny_run):
    """The overview's edit row takes edit.png's camera: across the bent tail's motion, which the
    side view of the other rows looks along more."""
    from ngc_gen.shape import load_shapes
    from ngc_gen.viz.camera import curve_displacements, resolve_up, side_view

    run, _ = tiny_run
    meshes = [trimesh.load(run / "edit" / f, process=False)
              for f in ("undeformed.ply", "deformed.ply")]
    view = edit_row_view(run, meshes)
    before = load_shapes(run / "fit")["creature_0000"].gcs
    disp = curve_displacements(before, load_annotation(run / "edit/edited.yaml").gcs)
    M = disp.T @ disp
    side = side_view(np.concatenate([m.vertices for m in meshes]), resolve_up("auto", meshes[:1]))
    assert view is not None and view @ M @ view < 0.5 * (side @ M @ side)
    assert edit_row_view(run.parent, meshes) is None  # no edit step there: the side view

def test_resume_keeps_finished_steps(tiny_run):
    run, _ = tiny_run
    before = json.loads((run / "summary.json").read_text())
    stamp = (run / "fit/metrics.json").stat().st_mtime_ns
    r = run_entry("train.py", "experiment=demo", "pipeline.resume=true", f"hydra.run.dir={run}")
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.count("finished earlier, kept") == 5
    assert json.loads((run / "summary.json").read_text())["steps"] == before["steps"]
    assert (run / "fit/metrics.json").stat().st_mtime_ns == stamp  # not run again


def test_resume_needs_an_earlier_run(tmp_path):
    cfg = compose_config(overrides=["experiment=demo", "pipeline.resume=true",
                                    f"run_dir={tmp_path}"])
    with pytest.raises(DataError, match="summary.json does not exist"):
        run_pipeline(cfg)
    assert not any(tmp_path.iterdir())
