"""The creature generator that bench/generate.py trains and bench/condition.py and
bench/reconstruct.py reuse: the recipe's options (conf/experiment/generate.yaml, the one
`make demo` runs), its shape-latent and diffusion runs from the generate bench's fit cache
(trained when the recipe has none), and the meshes, point clouds and metric rows of generated
shapes (also the animals and transfer benches')."""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from bench._harness import FitCache, cached_stage

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "bench/runs/generate"


def recipe_args(ap: argparse.ArgumentParser) -> None:
    """The training recipe's options (dataset, samples, steps)."""
    ap.add_argument("--n", type=int, default=64, help="creatures in the dataset")
    ap.add_argument("--test-fraction", type=float, default=0.25)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=50_000, help="prepare.n_samples per shape")
    ap.add_argument("--batch-size", type=int, default=None,
                    help="default: conf/experiment/generate.yaml's")
    ap.add_argument("--shape-latent-steps", type=int, default=None,
                    help="default: conf/experiment/generate.yaml's")
    ap.add_argument("--diffusion-steps", type=int, default=None,
                    help="default: conf/experiment/generate.yaml's")
    ap.add_argument("--refit", action="store_true",
                    help="train the shape-latent and diffusion runs again even if cached")


def overrides(args) -> list[str]:
    # the recipe is conf/experiment/generate.yaml's (make demo runs the same one)
    return ["experiment=generate", "data=creatures", f"data.n={args.n}",
            f"data.test_fraction={args.test_fraction}", f"data.seed={args.seed}",
            f"prepare.n_samples={args.samples}",
            f"prepare.cache_dir={ROOT}/.cache/prepared/creatures_gen{args.samples // 1000}k",
            *([f"batch_size={args.batch_size}"] if args.batch_size else []),
            "trainer.enable_progress_bar=false", "logger=csv", f"seed={args.seed}"]


def compose_batch_size() -> int:
    """The recipe's batch size (conf/experiment/generate.yaml)."""
    from ngc_gen.app.runtime.config import compose_config

    return int(compose_config(overrides=["experiment=generate"]).batch_size)


def train(args) -> dict:
    """The recipe's shape-latent and diffusion runs from the generate bench's fit cache
    (.cache/bench/fits/generate), each keyed by its stage's whole config and the dataset's
    identity (the diffusion config names its shape-latent run, so a new shape-latent fit means
    a new diffusion fit), else trained now; --refit trains both again. bench/runs/generate/
    shape_latent and diffusion link to them. -> {shape_latent, diffusion (their metrics),
    shape_latent_dir, diffusion_dir, shape_latent_stage_s (when trained in this call)}."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.train_diffusion import run_diffusion
    from ngc_gen.app.stages.train_shape_latent import run_shape_latent

    cache, refit = FitCache("generate"), getattr(args, "refit", False)
    times = {}
    sl = cached_stage(cache, "shape_latent", compose_config(overrides=overrides(args) + [
        "stage=shape_latent", "shape_latent.preview=0"] + (
            [f"shape_latent.max_steps={args.shape_latent_steps}"] if args.shape_latent_steps
            else [])), run_shape_latent, refit, RUNS / "shape_latent")
    if not sl.reused:
        times["shape_latent_stage_s"] = sl.info["stage_s"]
    diff = cached_stage(cache, "diffusion", compose_config(overrides=overrides(args) + [
        "stage=diffusion", f"shape_latent_run={sl.run_dir}"] + (
            [f"diffusion.max_steps={args.diffusion_steps}"] if args.diffusion_steps else [])),
        run_diffusion, refit, RUNS / "diffusion")
    sl_dir, diff_dir = sl.run_dir, diff.run_dir
    sl = json.loads((sl_dir / "metrics.json").read_text())
    diff = json.loads((diff_dir / "metrics.json").read_text())
    return {"shape_latent": sl, "diffusion": diff, "shape_latent_dir": sl_dir,
            "diffusion_dir": diff_dir, **times}


def mesh_set(gen, latents, names, out_dir, resolution):
    """Decode and mesh latents like sample.py does; returns (meshes, seconds per mesh)."""
    import trimesh

    from ngc_gen.app.runtime.outputs import extract_and_write
    from ngc_gen.generate.shapes import decode_shapes

    shapes = decode_shapes(gen.shape_latent, latents, names)
    written, secs = extract_and_write(gen, shapes, out_dir, resolution)
    return [trimesh.load(w.mesh, process=False) for w in written], secs


def clouds(meshes, n_points: int, seed: int):
    """(k, n, 3) surface clouds; an empty mesh counts as a cloud collapsed at the origin."""
    import numpy as np

    from ngc_gen.eval import sample_point_clouds
    from ngc_gen.eval.point_samples import is_empty

    out = np.zeros((len(meshes), n_points, 3))
    ok = [i for i, m in enumerate(meshes) if not is_empty(m)]
    if ok:
        out[ok] = sample_point_clouds([meshes[i] for i in ok], n_points, seed)
    return out, len(meshes) - len(ok)


def rows_for(sets: dict, ref_meshes, points: int) -> dict:
    """{row: {mmd_cd, cov_cd, nna_cd}} of each row's sets against one reference."""
    import numpy as np

    from ngc_gen.eval import generation_metrics, pairwise_chamfer

    ref, _ = clouds(ref_meshes, points, 0)
    d_rr = pairwise_chamfer(ref)
    out = {}
    for key, groups in sets.items():
        per = [generation_metrics(clouds(g, points, 0)[0], ref, ref_ref=d_rr) for g in groups]
        out[key] = {k: float(np.mean([p[k] for p in per])) for k in ("mmd_cd", "cov_cd", "nna_cd")}
    return out
