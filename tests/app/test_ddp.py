"""`trainer=ddp`: two CPU processes (gloo) train one model. Each rank trains on its own batches,
gradients (of the decoder and of the per-shape codes, an nn.Embedding with dense gradients) are
averaged, so after N steps both ranks hold the same weights, codes included. The run is the
command a user types: Lightning starts rank 1 by running train.py again in the same run
directory."""
import json

import pytest
import torch
import trimesh
import yaml

from ..conftest import straight_gc
from ..helpers import run_entry

DUMP = "+callbacks.dump._target_=tests.app.rank_dump.RankDump"


def load_ranks(folder):
    return [torch.load(folder / f"rank{r}.pt", weights_only=True) for r in (0, 1)]


def assert_same_weights_from_different_batches(ranks, steps: int, moved: str):
    r0, r1 = ranks
    assert r0["world_size"] == r1["world_size"] == 2
    assert r0["step"] == r1["step"] == steps
    assert r0["ids"] != r1["ids"]  # each rank trained on its own share of the batches
    assert r0["state_dict"].keys() == r1["state_dict"].keys()
    for k, v in r0["state_dict"].items():
        assert torch.equal(v, r1["state_dict"][k]), k
    start = r0["start"][moved]
    assert not torch.equal(start, r0["state_dict"][moved])  # trained, not just synchronised


def test_two_cpu_processes_hold_identical_weights_after_n_steps(tmp_path):
    folder = tmp_path / "meshes"
    folder.mkdir()
    pill = trimesh.creation.capsule(height=1.2, radius=0.3)  # along z, turned onto x
    pill.apply_transform(trimesh.transformations.rotation_matrix(1.5707963, [0, 1, 0]))
    pill.export(folder / "pill.ply")
    (folder / "pill.yaml").write_text(yaml.safe_dump(  # two GCs: two codes of one shape
        {"name": "pill", "mesh": "pill.ply", "normalize": {"bound": 0.8},
         "gcs": [straight_gc("lower", -0.55, 0.0, (0.35, 0.35), (0.3, 0.3)),
                 straight_gc("upper", 0.0, 0.55, (0.35, 0.35), (0.3, 0.3))]}))
    run, dump = tmp_path / "run", tmp_path / "dump"
    r = run_entry("train.py", "stage=fit", "trainer=ddp", "data=folder", f"data.path={folder}",
                  f"paths.cache_dir={tmp_path}/cache", "prepare.n_samples=6000",
                  "prepare.coverage_samples=2000", "batch_size=512", "trainer.max_steps=6",
                  "extract.resolution=16", "threads=1", DUMP, f"+callbacks.dump.out_dir={dump}",
                  f"hydra.run.dir={run}", timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    ranks = load_ranks(dump)
    assert ranks[0]["state_dict"]["codes.weight"].shape[0] == 2
    assert_same_weights_from_different_batches(ranks, 6, "codes.weight")
    metrics = json.loads((run / "metrics.json").read_text())  # rank 0 extracts and scores
    assert metrics["steps"] == 6 and set(metrics["shapes"]) == {"pill"}


@pytest.mark.slow  # two 2-process runs on built creatures, ~2 min: `make test-all`
def test_shape_latent_and_diffusion_train_identical_weights_on_two_processes(tmp_path):
    common = ["trainer=ddp", "threads=1", "data=creatures", "data.n=4",
              f"data.out_dir={tmp_path}/data", f"prepare.cache_dir={tmp_path}/prepared",
              "prepare.n_samples=4000", "prepare.coverage_samples=4000", "batch_size=512", DUMP]
    sl, diff = tmp_path / "sl", tmp_path / "diff"
    r = run_entry("train.py", "stage=shape_latent", *common, "trainer.max_steps=6",
                  "shape_latent.latent_dim=16", "shape_latent.preview=0",
                  f"+callbacks.dump.out_dir={tmp_path}/dump_sl", f"hydra.run.dir={sl}")
    assert r.returncode == 0, r.stderr[-3000:]
    assert_same_weights_from_different_batches(load_ranks(tmp_path / "dump_sl"), 6,
                                               "latents.weight")
    r = run_entry("train.py", "stage=diffusion", *common, f"shape_latent_run={sl}",
                  "trainer.max_steps=6", "diffusion.denoiser.width=32",
                  "diffusion.denoiser.depth=1", "diffusion.batch_size=2",
                  "diffusion.batches_per_epoch=4", f"+callbacks.dump.out_dir={tmp_path}/dump_d",
                  f"hydra.run.dir={diff}")
    assert r.returncode == 0, r.stderr[-3000:]
    ranks = load_ranks(tmp_path / "dump_d")
    assert_same_weights_from_different_batches(ranks, 6, "net.model.out.weight")
    assert any(k.startswith("ema.") for k in ranks[0]["state_dict"])  # EMA weights agree too
    assert json.loads((diff / "metrics.json").read_text())["steps"] == 6
