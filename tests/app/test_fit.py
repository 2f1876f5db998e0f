"""`python train.py stage=fit` end to end on a small mesh: outputs, accuracy, resume."""
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from ngc_gen.lit.checkpoint import load_autodecoder

from ..helpers import ROOT, run_entry

FAST = ["stage=fit", "data=folder", "model=small", "batch_size=2048", "prepare.n_samples=20000",
        "extract.resolution=64", "trainer.enable_progress_bar=false"]


@pytest.fixture(scope="module")
def torus_folder(tmp_path_factory):
    d = tmp_path_factory.mktemp("meshes")
    trimesh.creation.torus(major_radius=0.6, minor_radius=0.25).export(d / "torus.ply")
    return d


def fit(folder, run_dir, cache, *extra):
    return run_entry("train.py", *FAST, f"data.path={folder}", f"paths.cache_dir={cache}",
                     f"hydra.run.dir={run_dir}", *extra)


def final_l1(run_dir: Path) -> float:
    rows = (run_dir / "logs/metrics.csv").read_text().strip().splitlines()
    header = rows[0].split(",")
    col = header.index("train/l1")
    vals = [float(r.split(",")[col]) for r in rows[1:] if r.split(",")[col]]
    return float(np.mean(vals[-3:]))


@pytest.fixture(scope="module")
def torus_run(torus_folder, tmp_path_factory):
    base = tmp_path_factory.mktemp("torus_fit")
    r = fit(torus_folder, base / "run", base / "cache", "trainer.max_steps=300",
            "trainer.log_every_n_steps=10")
    return base / "run", r


def test_fit_recovers_a_watertight_mesh(torus_run):
    run, r = torus_run
    assert r.returncode == 0, r.stderr[-3000:]
    assert (run / "checkpoints/last.ckpt").is_file() and (run / "config.yaml").is_file()
    metrics = json.loads((run / "metrics.json").read_text())
    torus = metrics["shapes"]["torus"]
    # measured 9e-4 after 300 steps (an untrained network gives > 1e-2): bound with headroom
    assert torus["cd"] < 3e-3, torus
    assert torus["watertight"] and torus["gt_watertight"]
    assert metrics["steps"] == 300 and metrics["start_step"] == 0
    module = load_autodecoder(run / "checkpoints/last.ckpt")  # weights_only: plain hparams
    assert module.kind == "ngc" and module.hparams.decoder["code_dim"] == 64
    mesh = trimesh.load(run / "meshes/torus.ply")
    assert mesh.is_watertight
    parts = mesh.split(only_watertight=False)
    assert max(len(p.faces) for p in parts) > 0.95 * len(mesh.faces)  # one torus, few specks
    assert "torus" in r.stdout and "cd" in r.stdout
    # the junction measure of every fit (ngc_gen.eval.junctions), per shape and in the mean
    for key in ("junction_ratio_dist", "junction_ratio_normal", "junction_share",
                "extra_pieces", "gt_pieces"):
        assert key in torus and key in metrics["mean"], key
    assert torus["gt_pieces"] == 1 and torus["pieces"] >= 1
    assert "extra_pieces" in r.stdout


@pytest.mark.slow  # three short fits in subprocesses, ~2 min: `make test-all`
def test_resume_after_kill_continues_to_the_same_step(torus_folder, tmp_path):
    steps, cache = 600, tmp_path / "cache"
    base = tmp_path / "uninterrupted"
    r = fit(torus_folder, base, cache, f"trainer.max_steps={steps}", "extract.resolution=32")
    assert r.returncode == 0, r.stderr[-3000:]

    run = tmp_path / "killed"
    args = [sys.executable, str(ROOT / "train.py"), *FAST, f"data.path={torus_folder}",
            f"paths.cache_dir={cache}", f"hydra.run.dir={run}", f"trainer.max_steps={steps}",
            "extract.resolution=32"]
    p = subprocess.Popen(args, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    ckpt = run / "checkpoints/last.ckpt"
    deadline = time.time() + 300
    while not ckpt.exists() and time.time() < deadline and p.poll() is None:
        time.sleep(0.2)
    time.sleep(0.5)
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert ckpt.exists() and not (run / "metrics.json").exists(), "run finished before the kill"
    saved_step = torch.load(ckpt, map_location="cpu", weights_only=True)["global_step"]
    assert 0 < saved_step < steps

    r = fit(torus_folder, run, cache, f"trainer.max_steps={steps}", "extract.resolution=32",
            f"ckpt_path={run}")  # a run directory: its checkpoints/last.ckpt
    assert r.returncode == 0, r.stderr[-3000:]
    resumed = json.loads((run / "metrics.json").read_text())
    assert resumed["start_step"] == saved_step  # 0 if the checkpoint were ignored
    assert resumed["steps"] == steps
    a, b = final_l1(base), final_l1(run)
    assert abs(a - b) < 0.5 * max(a, b), (a, b)  # within training noise of each other


def test_reconstruct_puts_a_new_mesh_into_the_fit_with_the_decoder_frozen(torus_run, tmp_path):
    """stage=reconstruct: only the new shape's codes move; the result is a fit checkpoint that
    edit.py opens, and the new mesh is recovered about as well as the fitted one."""
    from ngc_gen.app.stages.registry import run_stage
    from ngc_gen.shape import load_shapes

    from ..helpers import compose_config

    run, _ = torus_run
    folder = tmp_path / "new"
    folder.mkdir()
    trimesh.creation.torus(major_radius=0.6, minor_radius=0.2).export(folder / "thin.ply")
    out = tmp_path / "rec"
    metrics = run_stage(compose_config(overrides=[
        "stage=reconstruct", f"run={run}", "data=folder", f"data.path={folder}",
        f"paths.cache_dir={tmp_path / 'cache'}", "prepare.n_samples=20000", "batch_size=2048",
        "reconstruct.max_steps=150", "extract.resolution=64", "trainer.enable_progress_bar=false",
        f"run_dir={out}"]))
    fitted = json.loads((run / "metrics.json").read_text())["shapes"]["torus"]["cd"]
    assert metrics["shapes"]["thin"]["cd"] < max(3 * fitted, 3e-3), (metrics["shapes"], fitted)
    before = load_autodecoder(run / "checkpoints/last.ckpt").decoder.state_dict()
    after = load_autodecoder(out / "checkpoints/last.ckpt").decoder.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)  # the decoder never moved
    assert list(load_shapes(out)) == ["thin"]  # what edit.py run=<out> opens


def test_fit_picture_names_every_gc_of_every_shape(tmp_path):
    """meshes.png's rows: the ground truth carries its GC surfaces and one label per GC (the
    names edit programs use, at each curve's middle) beside the fitted mesh."""
    from ngc_gen.app.stages.fit import comparison_rows
    from ngc_gen.geometry import GeneralizedCylinder

    from ..conftest import straight_gc

    box = trimesh.creation.box()
    (tmp_path / "meshes").mkdir()
    for name in ("a", "b"):
        box.export(tmp_path / "meshes" / f"{name}.ply")
    gt = {n: (box.vertices, box.faces) for n in ("a", "b")}
    gcs = {"a": [GeneralizedCylinder.from_dict(straight_gc("tail", -0.5, 0.0)),
                 GeneralizedCylinder.from_dict(straight_gc("head", 0.0, 0.5))],
           "b": [GeneralizedCylinder.from_dict(straight_gc("body", -0.5, 0.5))]}
    rows = comparison_rows(gt, tmp_path / "meshes", gcs)
    (truth, shell, labels), fitted = rows[0]
    assert [n for n, _ in labels] == ["tail", "head"]
    assert np.allclose([p for _, p in labels], [[-0.25, 0, 0], [0.25, 0, 0]])
    assert len(shell.faces) > 0 and len(fitted.faces) == len(box.faces)
    assert [n for n, _ in rows[1][0][2]] == ["body"]
    plain = comparison_rows(gt, tmp_path / "meshes")  # DeepSDF: no GCs, plain meshes
    assert all(isinstance(c, trimesh.Trimesh) for r in plain for c in r)
