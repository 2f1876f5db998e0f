"""Generation end to end on a tiny run: `train.py stage=shape_latent` -> `stage=diffusion` ->
`sample.py` (generate, interpolate, mix, condition), the files a generated shape needs to be
edited, seed reproducibility, and clear errors (exit 2) for bad inputs."""
import json

import numpy as np
import pytest
import torch
import trimesh
from hydra.errors import ConfigCompositionException, MissingConfigException
import yaml

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.shape import autodecoder_mesh, recorded_gcs
from ngc_gen.app.stages.sample import generate, interpolate, mix, run_sample
from ngc_gen.generate import load_generator
from ngc_gen.lit.checkpoint import load_autodecoder
from ngc_gen.app.stages.train_diffusion import run_diffusion

from ..helpers import compose_config, run_entry

RES = 24


@pytest.fixture(scope="module")
def runs(tmp_path_factory, single_thread):
    base = tmp_path_factory.mktemp("generation")
    mp = pytest.MonkeyPatch()
    mp.setenv("OMP_NUM_THREADS", "1")
    common = ["data=creatures", "data.n=4", f"data.out_dir={base}/data",
              f"prepare.cache_dir={base}/prepared", "prepare.n_samples=4000",
              "prepare.coverage_samples=4000", "batch_size=1024",
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
                      f"extract.resolution={RES}", "progress=false", f"hydra.run.dir={out['gen']}")
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
    n_params = json.loads((sl / "metrics.json").read_text())["n_params"]
    # explicit latents: the GC parameters, then shape_latent.latent_dim=16 free entries
    assert lat["names"] == split["train"] and lat["latents"].shape == (3, n_params + 16)
    assert (sl / "meshes" / f"{split['train'][0]}.ply").is_file()
    metrics = json.loads((sl / "metrics.json").read_text())
    assert metrics["steps"] == 60 and metrics["n_params"] == 266
    assert json.loads((diff / "metrics.json").read_text())["n_latents"] == 3


def test_generate_writes_editable_shapes(runs, gen):
    out = runs["gen"]
    lat = torch.load(out / "latents.pt", weights_only=True)
    assert lat["names"] == ["sample_000", "sample_001"]
    assert lat["latents"].shape == (2, gen.shape_latent.latents.weight.shape[1])
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
        assert [g.to_dict() for g in recorded_gcs(metas[i])] == [g.to_dict() for g in ann.gcs]
        assert metas[i]["n_codes"] == 10
        torch.testing.assert_close(edit.codes.weight[10 * i:10 * (i + 1)],
                                   gen.shape_latent.decode(lat["latents"][i:i + 1])[1][0])
        again = autodecoder_mesh(edit, i, RES, chunk=2048).mesh  # re-extracted from the checkpoint
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


def test_default_mix_gives_a_part_closer_to_b_than_to_a(gen):
    """sample.py mode=mix's default (the edit op's rule): B's part, attached at A's joint. In
    the frame of the part's start (joint), the mixed part's surface is near B's, not A's."""
    from ngc_gen.eval import chamfer
    from ngc_gen.generate import decode_shapes
    from ngc_gen.shape.mixing import start_frame

    sa, sb = decode_shapes(gen.shape_latent, gen.sample_latents([0, 1], seed=0), ["a", "b"])
    mixed = sa.with_part("tail", sb)

    def part_in_joint_frame(shape):
        gc = shape.gcs[shape.index("tail")]
        v = np.asarray(shape.mesh(40, chunk=4096, progress=False).mesh.vertices)
        v = v[np.asarray(gc.contains(v))]
        F = start_frame(gc)  # rows: joint point, tangent, normal, binormal
        return (v - F[0]) @ F[1:].T

    pa, pb, pm = (part_in_joint_frame(s) for s in (sa, sb, mixed))
    assert chamfer(pm, pb) < 0.5 * chamfer(pm, pa)


def test_mix_with_zero_weight_is_shape_a(gen, tmp_path):
    mix(gen, tmp_path / "w0", a=0, b=1, part="tail", blend="constant", blend_params={"w": 0.0},
        geometry="target", resolution=RES, progress=False)
    a = trimesh.load(tmp_path / "w0/sample_000.ply", process=False)
    m = trimesh.load(tmp_path / "w0/mix_tail.ply", process=False)
    from ngc_gen.eval import chamfer  # the mixed GC goes through the per-GC blend path:
    assert chamfer(a.vertices, m.vertices) < 1e-10  # equal to float rounding
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
        return run_sample(compose_config("sample", [f"out_dir={tmp_path}", "extract.resolution=16",
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
    with pytest.raises(DataError, match="is a checkpoint of a `train.py stage=fit` run, not of a"):
        sample(f"run={runs['gen'] / 'shapes.ckpt'}")
    with pytest.raises(DataError, match="no training shape named 'nobody'"):
        sample(f"run={runs['diff']}", "mode=interpolate", "a=nobody")
    with pytest.raises(MissingConfigException, match="mode/dream"):   # Hydra lists the modes
        sample(f"run={runs['diff']}", "mode=dream")
    with pytest.raises(ConfigCompositionException, match="steps"):    # interpolate's setting
        sample(f"run={runs['diff']}", "mode=generate", "steps=3")


def test_entry_point_exits_2_with_a_message(tmp_path):
    r = run_entry("sample.py", f"run={tmp_path / 'missing'}", f"hydra.run.dir={tmp_path}/o")
    assert r.returncode == 2 and "error:" in r.stderr and "does not exist" in r.stderr
    assert "Traceback" not in r.stderr


def test_edit_runs_unchanged_on_a_generated_shape(runs, tmp_path):
    """The generated shapes.ckpt + YAML go through edit.py's code path as a fitted shape does."""
    from ngc_gen.app.stages.edit_shapes import run_edit

    run_edit(compose_config("edit", [f"run={runs['gen']}", "edit=bent_tail",  # sample.py's dir
                                     "shape=sample_001", "extract.resolution=16",
                                     "extract.chunk=2048",
                                     f"out_dir={tmp_path}"]))
    edited = load_annotation(tmp_path / "edited.yaml")
    assert edited.gc_names == load_annotation(runs["gen"] / "sample_001.yaml").gc_names
    assert len(trimesh.load(tmp_path / "deformed.ply", process=False).faces) > 0


def test_reconstruct_a_held_out_creature_and_interpolate_to_a_generated_one(runs, tmp_path):
    """stage=reconstruct into the shape-latent run: one latent for the held-out creature (the
    decoders frozen), then its codes refined; sample.py interpolates from it to a generated
    shape by name."""
    from ngc_gen.app.stages.registry import run_stage

    base = runs["sl"].parent
    out = tmp_path / "rec"
    common = ["data=creatures", "data.n=4", f"data.out_dir={base}/data",
              f"prepare.cache_dir={base}/prepared", "prepare.n_samples=4000",
              "prepare.coverage_samples=4000", "batch_size=1024",
              "trainer.enable_progress_bar=false"]
    metrics = run_stage(compose_config(overrides=[
        "stage=reconstruct", f"run={runs['sl']}", *common, "data.split=test",
        "reconstruct.max_steps=40", "reconstruct.refine_steps=20", f"extract.resolution={RES}",
        f"run_dir={out}"]))
    held_out = json.loads((base / "data/split.json").read_text())["test"]
    # the code refinement starts at the latent's own codes (same field, same code order) and
    # fits the shape better
    l1 = metrics["refine_l1"]
    assert l1["before"] == pytest.approx(l1["latent"], rel=1e-5)
    assert l1["after"] < 0.99 * l1["before"]
    lat = torch.load(out / "latents.pt", weights_only=True)
    width = torch.load(runs["sl"] / "latents.pt", weights_only=True)["latents"].shape[1]
    assert lat["names"] == held_out and lat["latents"].shape == (1, width)
    assert set(metrics["shapes"]) == set(held_out) and (out / "shapes.ckpt").is_file()
    # every file explained (metrics.json and the printout), and the picture of input vs result
    from ngc_gen.app.stages.reconstruct_shapes import OUTPUTS
    assert metrics["outputs"] == OUTPUTS and "meshes/<name>.ply" in OUTPUTS
    assert json.loads((out / "metrics.json").read_text())["outputs"] == OUTPUTS
    assert (out / "reconstruct.png").stat().st_size > 1000
    # the reconstructed shape keeps the input's GCs (the frames its codes were fitted in), up to
    # the similarity that normalises the written mesh; decoded GCs would miss them by ~0.4 std
    given = np.concatenate([g.curve.points for g in load_annotation(
        base / "data" / f"{held_out[0]}.yaml").gcs])
    kept = np.concatenate([g.curve.points for g in load_annotation(
        out / "shapes" / f"{held_out[0]}.yaml").gcs])
    a, b = given - given.mean(0), kept - kept.mean(0)
    scale = float((a * b).sum() / (a * a).sum())
    assert np.abs(a * scale - b).max() < 1e-6 * max(1.0, np.abs(b).max())
    run_sample(compose_config("sample", [
        f"run={runs['diff']}", "mode=interpolate", f"latents={out / 'latents.pt'}",
        f"a={held_out[0]}", "b=0", "steps=3", f"extract.resolution={RES}", "progress=false",
        "picture=false", f"out_dir={tmp_path / 'interp'}"]))
    z = torch.load(tmp_path / "interp/latents.pt", weights_only=True)["latents"]
    assert torch.equal(z[0], lat["latents"][0])
    with pytest.raises(DataError, match=f"named latents of size {width}"):
        load_generator(runs["diff"]).add_latents(runs["sl"] / "checkpoints/last.ckpt")


def test_condition_mode_takes_the_given_gcs(runs, tmp_path, write_yaml):
    """`sample.py mode=condition gcs=<held-out creature's annotation>`: shapes + YAMLs whose GCs
    are the given ones (replace), in the given frame, plus the picture and an edit checkpoint."""
    from ngc_gen.data.procedural.creatures import build_creatures

    data = runs["sl"].parent / "data"
    split = json.loads((data / "split.json").read_text())
    # the held-out creature: built here (reused if another test built it), not by the fixture
    build_creatures(data, 4, only=split["test"][:1])
    given = data / f"{split['test'][0]}.yaml"
    out = tmp_path / "cond"
    r = run_entry("sample.py", f"run={runs['diff']}", "mode=condition", f"gcs={given}", "n=2",
                  "seed=0", f"extract.resolution={RES}", "progress=false", f"hydra.run.dir={out}")
    assert r.returncode == 0, r.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["mode"] == "condition" and len(summary["gc_err_std"]) == 2
    want = [g.to_dict() for g in load_annotation(given).gcs]
    for name in ("cond_000", "cond_001"):
        ann = load_annotation(out / f"{name}.yaml")
        assert ann.bound is None                      # the given GCs' frame: normalize: false
        got = [g.to_dict() for g in ann.gcs]
        assert [g["name"] for g in got] == [g["name"] for g in want]
        for a, b in zip(got, want):
            np.testing.assert_allclose(a["curve"]["points"], b["curve"]["points"], atol=1e-9)
            np.testing.assert_allclose([k["radii"] for k in a["keys"]],
                                       [k["radii"] for k in b["keys"]], atol=1e-9)
            np.testing.assert_allclose(a["caps"], b["caps"], atol=1e-9)
        assert len(trimesh.load(out / f"{name}.ply", process=False).faces) > 0
    assert (out / "shapes.png").is_file() and (out / "condition.yaml").is_file()
    metas = load_autodecoder(out / "shapes.ckpt").hparams.meta["shapes"]
    assert [m["name"] for m in metas] == ["cond_000", "cond_001"]

    bad = yaml.safe_load(given.read_text())
    bad["gcs"][0]["name"] = "wing"
    with pytest.raises(DataError, match="GC 'wing'.*no GC named 'wing' in the template"):
        run_sample(compose_config("sample", [
            f"run={runs['diff']}", "mode=condition", f"gcs={write_yaml(bad)}",
            f"out_dir={tmp_path}/bad", "extract.resolution=16", "progress=false"]))
    assert not (tmp_path / "bad").exists()            # nothing written
