"""Generation benchmark (paper Sec. 4.4, PointFlow / LION metrics): shape latents + EDM on the
training creatures, then MMD-CD, COV-CD and 1-NNA-CD of generated shapes against held-out
creatures never seen in training.

    python bench/generate.py [--n 64] [--shape-latent-steps N] [--diffusion-steps N]

The recipe (steps, learning rates) is conf/experiment/generate.yaml's, the one make demo runs.

Rows (each the mean over sets of as many shapes as the held-out set: COV and 1-NNA of one set of
16 move in steps of 6% and vary by +-10% between sets; 2048 surface points per shape, squared
Chamfer, all meshes in the dataset's normalised frame: bounding box centred, longest side 1.6):
  generated   EDM samples (deterministic Heun, 18 steps) decoded to GCs + codes, meshed at 128^3
  train_set   the ceiling: ground-truth training meshes
  train_recon the same training shapes' latents decoded and meshed like generated ones
  noise       the floor: latents ~ N(mean, std^2) per dimension of the trained latents, no
              diffusion, decoded and meshed the same way
Writes bench/results/generate.json (with the machine record, bench/_harness.py) and
generate.png; its table is bench/README.md's (bench/report.py). The trained runs are kept in the
bench's fit cache (keyed by their whole recipe; bench/runs/generate/shape_latent and diffusion
link to the latest), the samples go to bench/runs/generate/.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._harness import (Bench, FitCache, config_recipe, dataset_identity,  # noqa: E402
                            link_latest)
RUNS = ROOT / "bench/runs/generate"
RESULTS = ROOT / "bench/results"


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
    """The recipe's shape-latent and diffusion runs from the bench's fit cache
    (.cache/bench/fits/generate), each keyed by its stage's whole config and the dataset's
    identity (the diffusion config names its shape-latent run, so a new shape-latent fit means
    a new diffusion fit), else trained now; --refit trains both again. bench/runs/generate/
    shape_latent and diffusion link to them. -> {shape_latent, diffusion (their metrics),
    shape_latent_dir, diffusion_dir, shape_latent_stage_s (when trained in this call)}."""
    from omegaconf import open_dict

    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.train_diffusion import run_diffusion
    from ngc_gen.app.stages.train_shape_latent import run_shape_latent

    cache = FitCache("generate")

    def stage(name: str, cfg, run):
        def fit(run_dir: Path) -> dict:
            with open_dict(cfg):
                cfg.run_dir = str(run_dir)
            t0 = time.perf_counter()
            run(cfg)
            return {"stage_s": time.perf_counter() - t0, "label": name}

        recipe = {"stage": name, "config": config_recipe(cfg), "data": dataset_identity(cfg)}
        f = cache.get(recipe, fit, refit=getattr(args, "refit", False))
        link_latest(RUNS / name, f.run_dir)
        return f

    times = {}
    sl = stage("shape_latent", compose_config(overrides=overrides(args) + [
        "stage=shape_latent", "shape_latent.preview=0"] + (
            [f"shape_latent.max_steps={args.shape_latent_steps}"] if args.shape_latent_steps
            else [])), run_shape_latent)
    if not sl.reused:
        times["shape_latent_stage_s"] = sl.info["stage_s"]
    diff = stage("diffusion", compose_config(overrides=overrides(args) + [
        "stage=diffusion", f"shape_latent_run={sl.run_dir}"] + (
            [f"diffusion.max_steps={args.diffusion_steps}"] if args.diffusion_steps else [])),
        run_diffusion)
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
    from ngc_gen.eval import sample_point_clouds
    from ngc_gen.eval.sampling import is_empty

    out = np.zeros((len(meshes), n_points, 3))
    ok = [i for i, m in enumerate(meshes) if not is_empty(m)]
    if ok:
        out[ok] = sample_point_clouds([meshes[i] for i in ok], n_points, seed)
    return out, len(meshes) - len(ok)


def render(meshes, names, path: Path, cols: int = 4) -> None:
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    rows = int(np.ceil(len(meshes) / cols))
    p = pv.Plotter(off_screen=True, shape=(rows, cols), window_size=(320 * cols, 300 * rows),
                   border=False)
    for i, (m, name) in enumerate(zip(meshes, names)):
        p.subplot(i // cols, i % cols)
        if len(m.faces):
            poly = pv.PolyData.from_regular_faces(np.asarray(m.vertices), np.asarray(m.faces))
            p.add_mesh(poly, color="#d9b38c", smooth_shading=True)
        p.add_text(name, font_size=9)
        p.camera_position = [(2.2, -2.6, 1.4), (0, 0, 0), (0, 0, 1)]
    p.render()
    path.parent.mkdir(parents=True, exist_ok=True)
    p.screenshot(str(path))
    p.close()


def recipe_args(ap: argparse.ArgumentParser) -> None:
    """The training recipe's options (dataset, samples, steps), shared with bench/condition.py,
    which reuses these runs."""
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    recipe_args(ap)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--points", type=int, default=2048)
    ap.add_argument("--sets", type=int, default=10,
                    help="disjoint sets of n_reference generated / noise shapes to average over")
    ap.add_argument("--train-subsets", type=int, default=20,
                    help="random subsets of n_reference training shapes to average over")
    ap.add_argument("--no-recon", action="store_true", help="skip the train_recon row")
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (on a busy 2-core machine one thread trained 12x faster "
                         "than two: 59 vs 725 ms a step, measured)")
    args = ap.parse_args()
    bench = Bench("generate")  # timings need an idle machine: its load is recorded

    import torch
    import trimesh

    torch.set_num_threads(args.threads)

    from ngc_gen.app.runtime.config import repo_root
    from ngc_gen.data.datasets import Creatures
    from ngc_gen.eval import generation_metrics, pairwise_chamfer
    from ngc_gen.app.stages.sample import generate
    from ngc_gen.generate import load_generator

    t_start = time.perf_counter()
    data = Creatures("creatures", repo_root() / f".cache/datasets/creatures_n{args.n}_s{args.seed}",
                     n=args.n, seed=args.seed, test_fraction=args.test_fraction)
    data.shapes()  # builds the dataset if needed
    split = json.loads((data.out_dir / "split.json").read_text())
    load = lambda names: [trimesh.load(data.out_dir / f"{n}.ply", process=False)  # noqa: E731
                          for n in names]
    ref_meshes, train_meshes = load(split["test"]), load(split["train"])
    n_ref = len(ref_meshes)
    print(f"{len(train_meshes)} training / {n_ref} held-out creatures")

    runs = train(args)
    gen = load_generator(runs["diffusion_dir"])
    n_gen = args.sets * n_ref

    sampled = generate(gen, RUNS / "samples", n=n_gen, seed=args.seed,
                       resolution=args.resolution)
    gen_names = sorted(sampled["shapes"])
    gen_meshes = [trimesh.load(RUNS / "samples" / f"{n}.ply", process=False) for n in gen_names]
    noise_lat = gen.noise_latents(n_gen, seed=args.seed + 1, kind="fitted")
    noise_meshes, _ = mesh_set(gen, noise_lat, [f"noise_{i:03d}" for i in range(n_gen)],
                               RUNS / "noise", args.resolution)
    # training shapes: random subsets of n_ref (distinct shapes within a subset), the same for
    # the meshes and their decodings
    rng = np.random.default_rng(args.seed)
    train_sets = [rng.choice(len(train_meshes), n_ref, replace=False)
                  for _ in range(args.train_subsets)]
    sets = {"generated": [gen_meshes[i:i + n_ref] for i in range(0, n_gen, n_ref)],
            "noise": [noise_meshes[i:i + n_ref] for i in range(0, n_gen, n_ref)],
            "train_set": [[train_meshes[i] for i in s] for s in train_sets]}
    if not args.no_recon:
        assert gen.names == split["train"]
        recon, _ = mesh_set(gen, gen.train_latents, gen.names, RUNS / "train_recon",
                            args.resolution)
        sets["train_recon"] = [[recon[i] for i in s] for s in train_sets]

    ref, _ = clouds(ref_meshes, args.points, 0)
    d_rr = pairwise_chamfer(ref)
    res = {"n_reference": n_ref, "n_train": len(train_meshes), "points": args.points,
           "resolution": args.resolution, "shape_latent_steps": runs["shape_latent"]["steps"],
           "diffusion_steps": runs["diffusion"]["steps"],
           "batch_size": args.batch_size or compose_batch_size(),
           "samples_per_shape": args.samples, "seed": args.seed, "threads": args.threads,
           "convention": "2048 surface points per shape, squared Chamfer (sum of the two means), "
                         "normalised frame (bbox centred, longest side 1.6); fractions; each row "
                         "the mean over sets of n_reference shapes (per_set lists them): "
                         "disjoint sets of generated / noise shapes, random subsets of the "
                         "training shapes",
           "train_set_is": "ground-truth training meshes",
           "train_recon_is": "the training latents decoded (GCs + codes) and meshed like "
                             "generated shapes",
           "noise_is": "latents ~ N(mean, std^2) per dimension of the trained latents, decoded "
                       "with no diffusion",
           "n_sets": {}, "per_set": {}, "empty_meshes": {}}
    for key, groups in sets.items():
        per, empty = [], 0
        for meshes in groups:
            pts, e = clouds(meshes, args.points, 0)
            per.append(generation_metrics(pts, ref, ref_ref=d_rr))
            empty += e
        res[key] = {k: float(np.mean([p[k] for p in per])) for k in per[0]}
        res["per_set"][key], res["n_sets"][key], res["empty_meshes"][key] = per, len(per), empty
    res["timing"] = {"latent_s_per_shape": sampled["latent_s_per_shape"],
                     "mesh_s_per_shape": sampled["mesh_s_per_shape"],
                     "shape_latent_train_s": runs["shape_latent"]["train_s"],
                     "diffusion_train_s": runs["diffusion"]["train_s"],
                     "total_s": time.perf_counter() - t_start}
    res["shape_latent"] = {k: runs["shape_latent"][k] for k in ("l1", "param", "latent_norm2",
                                                                 "params", "steps")}
    res["diffusion"] = {k: runs["diffusion"][k] for k in (
        "edm_loss_untrained", "edm_loss_ema", "sample_to_train_median", "train_to_train_median",
        "steps")}
    render(gen_meshes[:8], gen_names[:8], RESULTS / "generate.png")
    from bench.report import table

    path = bench.write(res)
    print("\n" + table("generate", json.loads(path.read_text())))
    print(f"total {res['timing']['total_s'] / 60:.1f} min; results in {RESULTS}")


if __name__ == "__main__":
    main()
