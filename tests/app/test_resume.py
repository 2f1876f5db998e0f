"""Kill -9 and rerun the same command: preparation reuses the cache entries it finished, and the
training stages (fit, shape_latent, diffusion) pick up their run directory's last.ckpt. Each
test asserts that the rerun started at the checkpoint's step (a rerun that ignored the checkpoint
starts at 0 and fails it) and that nothing written before the kill was lost or corrupted."""
import csv
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import torch
import trimesh
import yaml

from ngc_gen import workspace
from ngc_gen.data.prepare import load_prepared

from ..conftest import straight_gc
from ..helpers import ROOT, run_entry

pytestmark = pytest.mark.slow  # each kills and reruns real commands: `make test-all`


def kill_when(args: list[str], ready, timeout: float = 900) -> None:
    """Run `python train.py args` and SIGKILL it (and any process it started) once ready()."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen([sys.executable, str(ROOT / "train.py"), *args], cwd=ROOT, env=env,
                             stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
        deadline = time.time() + timeout
        try:
            while time.time() < deadline and p.poll() is None and not ready():
                time.sleep(0.1)
            err.seek(0)
            assert p.poll() is None, "the run ended before the kill: " + \
                err.read().decode()[-2000:]
            assert ready(), "the run never got far enough to be killed"
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    assert p.returncode == -signal.SIGKILL


def ckpt_step(path: Path) -> int:
    try:
        return int(torch.load(path, map_location="cpu", weights_only=True)["global_step"])
    except (FileNotFoundError, RuntimeError, EOFError, KeyError):
        return -1


def csv_rows(run: Path) -> list[dict]:
    path = run / "logs" / "metrics.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def assert_resumed(run: Path, saved: int, steps: int, stdout: str, log_before: list[dict]):
    """The rerun started at `saved`, trained to `steps`, kept the log rows before `saved`, and
    left loadable checkpoints (no last-v1 beside last)."""
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["start_step"] == saved  # 0 if the checkpoint were ignored
    assert metrics["steps"] == steps
    assert f"resuming from {run / 'checkpoints' / 'last.ckpt'} (step {saved})" in stdout
    assert sorted(p.name for p in (run / "checkpoints").iterdir()) == ["best.ckpt", "last.ckpt"]
    assert ckpt_step(run / "checkpoints" / "last.ckpt") == steps
    kept = [r for r in log_before if int(r["step"]) < saved]
    rows = csv_rows(run)
    assert kept and rows[:len(kept)] == kept  # the history before the kill is still there
    logged = [int(r["step"]) for r in rows]
    assert logged == sorted(set(logged))  # and no step twice


def train_args(run: Path, *extra: str) -> list[str]:
    return [*extra, "trainer.enable_progress_bar=false", "trainer.log_every_n_steps=5",
            "+logger.flush_logs_every_n_steps=5", "callbacks.checkpoint.every_n_train_steps=20",
            "threads=1", f"hydra.run.dir={run}"]


def kill_and_resume(args: list[str], run: Path, steps: int):
    """Kill the run after its second checkpoint, rerun the same command; (saved step, the
    rerun's stdout, the log rows on disk at the kill)."""
    last = run / "checkpoints" / "last.ckpt"
    kill_when(args, lambda: ckpt_step(last) >= 40)
    saved = ckpt_step(last)
    assert 40 <= saved < steps and not (run / "metrics.json").exists()
    assert workspace.lock(run).is_file()  # the killed run's lock: the rerun takes it over
    log_before = csv_rows(run)
    r = run_entry("train.py", *args, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert not workspace.lock(run).exists()
    return saved, r.stdout, log_before


@pytest.fixture(scope="module")
def torus(tmp_path_factory):
    d = tmp_path_factory.mktemp("torus")
    trimesh.creation.torus(major_radius=0.6, minor_radius=0.25).export(d / "torus.ply")
    return d


def test_fit_resumes_from_last_ckpt(torus, tmp_path):
    run, steps = tmp_path / "run", 1000
    args = train_args(run, "stage=fit", "data=folder", f"data.path={torus}",
                      f"paths.cache_dir={tmp_path}/cache", "prepare.n_samples=20000",
                      "batch_size=2048", f"trainer.max_steps={steps}", "extract.resolution=32")
    saved, stdout, log_before = kill_and_resume(args, run, steps)
    assert_resumed(run, saved, steps, stdout, log_before)
    # resume=false refuses to start over in a directory that holds a run's checkpoints
    r = run_entry("train.py", *args, "resume=false")
    assert r.returncode == 2 and "resume = False" in r.stderr and "resume=true" in r.stderr
    # a checkpoint of another model (here: other encoding bands) is one line, not a traceback
    r = run_entry("train.py", *args, "model.decoder.pe_frequencies=4")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert "cannot resume from" in r.stderr and "size mismatch" in r.stderr
    assert "hydra.run.dir" in r.stderr


def test_prepare_keeps_the_cache_entries_it_finished(tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    for i in range(6):
        trimesh.creation.icosphere(subdivisions=3, radius=1 + 0.05 * i).export(
            folder / f"ball{i}.ply")
        (folder / f"ball{i}.yaml").write_text(yaml.safe_dump(
            {"name": f"ball{i}", "mesh": f"ball{i}.ply", "normalize": {"bound": 0.8},
             "gcs": [straight_gc("body", -0.3, 0.3)]}))
    cache = tmp_path / "cache"
    args = ["stage=prepare", "data=folder", f"data.path={folder}", f"prepare.cache_dir={cache}",
            "prepare.n_samples=300000", "threads=1", f"hydra.run.dir={tmp_path}/run"]
    kill_when(args, lambda: len(list(cache.glob("*.npz"))) >= 2)
    done = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in cache.glob("*.npz")}
    assert 2 <= len(done) < 6
    r = run_entry("train.py", *args, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = {line.split()[0]: line.split()[-1] for line in r.stdout.splitlines()
            if line.startswith("ball")}
    for name, (data, mtime) in done.items():  # reused as they were, not rewritten
        p = cache / name
        assert p.read_bytes() == data and p.stat().st_mtime_ns == mtime, name
        assert rows[p.stem] == "cache", rows
    assert sorted(p.name for p in cache.glob("*.npz")) == [f"ball{i}.npz" for i in range(6)]
    for p in cache.glob("*.npz"):
        load_prepared(p)  # complete files only (the killed write left no partial npz)


def test_shape_latent_and_diffusion_resume_from_last_ckpt(tmp_path):
    common = ["data=creatures", "data.n=4", f"data.out_dir={tmp_path}/data",
              f"prepare.cache_dir={tmp_path}/prepared", "prepare.n_samples=4000",
              "prepare.coverage_samples=4000", "batch_size=1024"]
    sl, steps = tmp_path / "sl", 600
    args = train_args(sl, "stage=shape_latent", *common, f"trainer.max_steps={steps}",
                      "shape_latent.latent_dim=16", "shape_latent.preview=0")
    saved, stdout, log_before = kill_and_resume(args, sl, steps)
    assert_resumed(sl, saved, steps, stdout, log_before)
    # explicit latents: the GC parameters, then shape_latent.latent_dim=16 free entries
    n_params = json.loads((sl / "metrics.json").read_text())["n_params"]
    assert torch.load(sl / "latents.pt", weights_only=True)["latents"].shape == (3, n_params + 16)

    diff, steps = tmp_path / "diff", 3000  # a tiny denoiser steps fast: room to kill it
    args = train_args(diff, "stage=diffusion", f"shape_latent_run={sl}",
                      f"trainer.max_steps={steps}", "diffusion.denoiser.width=64",
                      "diffusion.denoiser.depth=2")
    saved, stdout, log_before = kill_and_resume(args, diff, steps)
    assert_resumed(diff, saved, steps, stdout, log_before)
