"""Generation end to end on a tiny run: `train.py stage=shape_latent` -> `stage=diffusion` ->
`sample.py` (generate, interpolate, mix), the files a generated shape needs to be edited, seed
reproducibility, and clear errors (exit 2) for bad inputs."""
import json

import numpy as np
import pytest
import torch
import trimesh

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.extract.shapes import extract_shape, shape_gcs
from ngc_gen.generate import generate, interpolate, load_generator, mix, run_sample
from ngc_gen.lit.checkpoint import load_autodecoder
from ngc_gen.stages.diffusion import run_diffusion

from .helpers import compose_config, run_entry

RES = 24


@pytest.fixture(scope="module")
def runs(tmp_path_factory, single_thread):
    base = tmp_path_factory.mktemp("generation")
    mp = pytest.MonkeyPatch()
    mp.setenv("OMP_NUM_THREADS", "1")
    common = ["data=creatures", "data.n=4", f"data.out_dir={base}/data",
              f"prepare.cache_dir={base}/prepared", "prepare.n_samples=4000",
              "+prepare.coverage_samples=4000", "batch_size=1024",
              "trainer.enable_progress_bar=false", "trainer.log_every_n_steps=10"]
    out = {k: base / k for k in ("sl", "diff", "gen")}
    try:
        r = run_entry("train.py", "stage=shape_latent", *common, "trainer.max_steps=60",
                      "shape_latent.latent_dim=16", "shape_latent.lr=3e-3",
                      "shape_latent.latent_lr=3e-3", "shape_latent.preview=1",
                      f"shape_latent.preview_resolution={RES}", f"hydra.run.dir={out['sl']}")
        assert r.returncode == 0, r.stderr[-3000:]
        # in-process (the same composed config train.py runs): saves a process start
        run_diffusion(compose_config(overrides=[
            "stage=diffusion", f"shape_latent_run={out['sl']}", "trainer.max_steps=30",
            "diffusion.denoiser.width=32", "diffusion.denoiser.depth=1", "logger=csv",
            "trainer.enable_progress_bar=false", f"run_dir={out['diff']}"]))
        r = run_entry("sample.py", f"run={out['diff']}", "mode=generate", "n=2", "seed=0",
                      f"resolution={RES}", "progress=false", f"hydra.run.dir={out['gen']}")
        assert r.returncode == 0, r.stderr[-3000:]
    finally:
        mp.undo()
    return out


@pytest.fixture(scope="module")
def gen(runs):
    return load_generator(runs["diff"])


def test_stages_write_checkpoints_and_latents(runs):
    sl, diff = runs["sl"], runs["diff"]
    assert (sl / "checkpoints/last.ckpt").is_file() and (diff / "checkpoints/last.ckpt").is_file()
    lat = torch.load(sl / "latents.pt", weights_only=True)
    split = json.loads((sl.parent / "data/split.json").read_text())
    assert lat["names"] == split["train"] and lat["latents"].shape == (3, 16)
    assert (sl / "meshes" / f"{split['train'][0]}.ply").is_file()
    metrics = json.loads((sl / "metrics.json").read_text())
    assert metrics["steps"] == 60 and metrics["n_params"] == 266
    assert json.loads((diff / "metrics.json").read_text())["n_latents"] == 3


def test_generate_writes_editable_shapes(runs, gen):
    out = runs["gen"]
    lat = torch.load(out / "latents.pt", weights_only=True)
    assert lat["names"] == ["sample_000", "sample_001"] and lat["latents"].shape == (2, 16)
    assert (out / "shapes.png").is_file()  # sample.py's picture (picture=true by default)
    edit = load_autodecoder(out / "shapes.ckpt")          # the fit format edit.py loads
    metas = edit.hparams.meta["shapes"]
    assert [m["name"] for m in metas] == lat["names"]
    for i, name in enumerate(lat["names"]):
        ann = load_annotation(out / f"{name}.yaml")
        assert ann.mesh_path == (out / f"{name}.ply").resolve() and ann.bound == 0.8
        assert ann.gc_names == gen.shape_latent.template.names
        mesh = trimesh.load(out / f"{name}.ply", process=False)
        assert len(mesh.faces) > 0
        lo, hi = mesh.bounds                               # normalize: {bound: 0.8} is identity
        assert np.allclose((lo + hi) / 2, 0, atol=1e-6) and np.isclose((hi - lo).max(), 1.6)
        # the checkpoint's shape has the YAML's GCs and the shape's decoded codes
        assert [g.to_dict() for g in shape_gcs(metas[i])] == [g.to_dict() for g in ann.gcs]
        assert metas[i]["n_codes"] == 10
        torch.testing.assert_close(edit.codes.weight[10 * i:10 * (i + 1)],
                                   gen.shape_latent.decode(lat["latents"][i:i + 1])[1][0])
        again = extract_shape(edit, i, RES, chunk=2048).mesh  # re-extracted from the checkpoint
        step = 2.0 / (RES - 1)
        assert np.abs(again.bounds - mesh.bounds).max() < 2 * step


def test_same_seed_same_latents_and_meshes(runs, gen, tmp_path):
    saved = torch.load(runs["gen"] / "latents.pt", weights_only=True)["latents"]
    assert torch.equal(gen.sample_latents(range(2), seed=0), saved)
    assert torch.equal(gen.sample_latents([1], seed=0)[0], saved[1])   # independent of n
    assert not torch.equal(gen.sample_latents([0], seed=1)[0], saved[0])
    generate(gen, tmp_path, n=2, seed=0, resolution=RES, progress=False)
    assert torch.equal(torch.load(tmp_path / "latents.pt", weights_only=True)["latents"], saved)
    a = trimesh.load(tmp_path / "sample_001.ply", process=False)
    b = trimesh.load(runs["gen"] / "sample_001.ply", process=False)
    # same faces; vertices to float rounding (the network's rows come in batches of varying
    # size, and BLAS rounding may depend on a batch's size and memory alignment)
    assert np.array_equal(a.faces, b.faces)
    np.testing.assert_allclose(a.vertices, b.vertices, rtol=0, atol=1e-6)


@pytest.mark.parametrize("method", ["lerp", "slerp"])
def test_interpolation_ends_at_the_two_shapes(gen, tmp_path, method):
    name = gen.names[0]
    interpolate(gen, tmp_path, a=name, b=1, steps=3, seed=0, method=method, resolution=12,
                progress=False)
    z = torch.load(tmp_path / "latents.pt", weights_only=True)
    assert z["names"] == ["interp_00", "interp_01", "interp_02"]
    assert torch.equal(z["latents"][0], gen.train_latents[0])
    assert torch.equal(z["latents"][-1], gen.sample_latents([1], seed=0)[0])
    if method == "lerp":
        torch.testing.assert_close(z["latents"][1], (z["latents"][0] + z["latents"][2]) / 2)
    assert all((tmp_path / f"interp_0{k}.yaml").is_file() for k in range(3))


def test_mix_with_zero_weight_is_shape_a(gen, tmp_path):
    mix(gen, tmp_path / "w0", a=0, b=1, part="tail", blend="constant", blend_params={"w": 0.0},
        resolution=RES, progress=False)
    a = trimesh.load(tmp_path / "w0/sample_000.ply", process=False)
    m = trimesh.load(tmp_path / "w0/mix_tail.ply", process=False)
    # shape A's mesh comes from the batched decoder rows (NGCDecoder.sdf_rows), the mix from
    # the per-GC feature path: the same field up to float rounding
    assert np.array_equal(a.faces, m.faces)
    np.testing.assert_allclose(a.vertices, m.vertices, rtol=0, atol=1e-4)  # ~1e-3 voxel
    summary = mix(gen, tmp_path / "w1", a=0, b=1, part="tail", blend="truncated_linear",
                  blend_params={"t0": 0.0, "t1": 0.5}, resolution=12,
                  progress=False)
    assert summary["edit_shapes"] == ["sample_000", "sample_001"]
    assert load_annotation(tmp_path / "w1/mix_tail.yaml").gc_names[3] == "tail"
    with pytest.raises(DataError, match="no GC named 'wing'"):
        mix(gen, tmp_path / "bad", part="wing", resolution=RES)
    with pytest.raises(DataError, match="t0"):
        mix(gen, tmp_path / "bad", blend="truncated_linear", blend_params={"t0": 0.8, "t1": 0.2})


def test_bad_inputs_are_clear_errors(runs, tmp_path):
    def sample(*overrides):
        return run_sample(compose_config("sample", [f"out_dir={tmp_path}", "resolution=16",
                                                    "progress=false", *overrides]))

    with pytest.raises(DataError, match="not a shape-latent checkpoint"):
        run_diffusion(compose_config(overrides=["stage=diffusion", f"run_dir={tmp_path}/d",
                                                f"shape_latent_run={runs['diff']}"]))
    with pytest.raises(DataError, match="no shape-latent run given"):
        run_diffusion(compose_config(overrides=["stage=diffusion", f"run_dir={tmp_path}/d"]))

    with pytest.raises(DataError, match="no run given"):
        sample()
    with pytest.raises(DataError, match="needs a diffusion model"):
        sample(f"run={runs['sl']}", "mode=generate")
    with pytest.raises(DataError, match="neither a diffusion nor a shape-latent"):
        sample(f"run={runs['gen'] / 'shapes.ckpt'}")
    with pytest.raises(DataError, match="no training shape named 'nobody'"):
        sample(f"run={runs['diff']}", "mode=interpolate", "a=nobody")
    with pytest.raises(DataError, match="unknown mode"):
        sample(f"run={runs['diff']}", "mode=dream")


def test_entry_point_exits_2_with_a_message(tmp_path):
    r = run_entry("sample.py", f"run={tmp_path / 'missing'}", f"hydra.run.dir={tmp_path}/o")
    assert r.returncode == 2 and "error:" in r.stderr and "does not exist" in r.stderr
    assert "Traceback" not in r.stderr


def test_edit_runs_unchanged_on_a_generated_shape(runs, tmp_path):
    """The generated shapes.ckpt + YAML go through edit.py's code path as a fitted shape does."""
    from ngc_gen.edit.run import run_edit

    run_edit(compose_config("edit", [f"ckpt={runs['gen'] / 'shapes.ckpt'}", "edit=bent_tail",
                                     "shape=sample_001", "resolution=16", "chunk=2048",
                                     f"out_dir={tmp_path}"]))
    edited = load_annotation(tmp_path / "edited.yaml")
    assert edited.gc_names == load_annotation(runs["gen"] / "sample_001.yaml").gc_names
    assert len(trimesh.load(tmp_path / "deformed.ply", process=False).faces) > 0
