"""The same seed and config give bit-identical caches, weights and metrics on CPU, and the run
directory records every seed it used (seeds.json beside config.yaml)."""
import json

import pytest
import torch
import trimesh

from ngc_gen.app.stages.fit import run_fit

from ..helpers import compose_config

pytestmark = pytest.mark.usefixtures("single_thread")
TIMINGS = {"train_s", "extract_s", "seconds", "checkpoint"}  # and the run's own path


def without_timings(x):
    """The metrics without wall times and paths (which name the run directory)."""
    if isinstance(x, dict):
        return {k: without_timings(v) for k, v in x.items() if k not in TIMINGS}
    return x


def fit(folder, root):
    cfg = compose_config(overrides=[
        "stage=fit", "data=folder", f"data.path={folder}", f"paths.cache_dir={root}/cache",
        "prepare.n_samples=3000", "prepare.coverage_samples=2000", "batch_size=512",
        "trainer.max_steps=8", "trainer.enable_progress_bar=false", "extract.resolution=16",
        f"run_dir={root}/run", "seed=3", "metrics_seed=5"])
    return run_fit(cfg)


def test_same_seed_and_config_give_identical_runs(tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    trimesh.creation.torus(major_radius=0.6, minor_radius=0.25).export(folder / "torus.ply")
    a, b = tmp_path / "a", tmp_path / "b"
    ma, mb = fit(folder, a), fit(folder, b)
    assert without_timings(ma) == without_timings(mb) and ma["mean"]["cd"] > 0
    cache = "cache/prepared/meshes/torus.npz"
    assert (a / cache).read_bytes() == (b / cache).read_bytes()
    wa, wb = (torch.load(r / "run/checkpoints/last.ckpt", weights_only=True)["state_dict"]
              for r in (a, b))
    assert wa.keys() == wb.keys() and all(torch.equal(wa[k], wb[k]) for k in wa)
    assert (a / "run/meshes/torus.ply").read_bytes() == (b / "run/meshes/torus.ply").read_bytes()
    seeds = json.loads((a / "run/seeds.json").read_text())
    assert seeds["config"] == {"seed": 3, "prepare.seed": 0, "metrics_seed": 5, "annotate.seed": 0,
                               "data.annotate.seed": 0}
