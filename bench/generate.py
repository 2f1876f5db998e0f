"""Generation benchmark (paper Sec. 4.4, PointFlow / LION metrics): shape latents + EDM on the
training creatures, then MMD-CD, COV-CD and 1-NNA-CD of generated shapes against held-out
creatures never seen in training.

    python -m bench.generate [--n 64] [--shape-latent-steps N] [--diffusion-steps N]

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
import time
from pathlib import Path

from bench._generation import (RUNS, clouds, compose_batch_size, mesh_set, recipe_args,
                               train)
from bench._harness import Bench
from bench._tables import pct, sci

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench/results"


def render(meshes, names, path: Path, cols: int = 4) -> None:
    import numpy as np

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


def parse_args():
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
    return ap.parse_args()


def score(sets: dict, ref, d_rr, points: int, res: dict) -> None:
    """Each row's metrics against the reference clouds `ref` (pairwise distances `d_rr`), the
    mean over its sets, into `res` (with per_set, n_sets and empty_meshes)."""
    import numpy as np

    from ngc_gen.eval import generation_metrics

    for key, groups in sets.items():
        per, empty = [], 0
        for meshes in groups:
            pts, e = clouds(meshes, points, 0)
            per.append(generation_metrics(pts, ref, ref_ref=d_rr))
            empty += e
        res[key] = {k: float(np.mean([p[k] for p in per])) for k in per[0]}
        res["per_set"][key], res["n_sets"][key], res["empty_meshes"][key] = per, len(per), empty


def sample_sets(gen, args, train_meshes: list, n_ref: int, split: dict):
    """The rows' sets of n_ref meshes: generated and noise shapes (disjoint sets), training
    meshes and their decodings (random subsets, distinct shapes within one). -> (generate's
    record, generated names, generated meshes, {row: [set of meshes]})."""
    import numpy as np
    import trimesh

    from ngc_gen.app.stages.sample import generate

    n_gen = args.sets * n_ref
    sampled = generate(gen, RUNS / "samples", n=n_gen, seed=args.seed,
                       resolution=args.resolution)
    gen_names = sorted(sampled["shapes"])
    gen_meshes = [trimesh.load(RUNS / "samples" / f"{n}.ply", process=False) for n in gen_names]
    noise_lat = gen.noise_latents(n_gen, seed=args.seed + 1, kind="fitted")
    noise_meshes, _ = mesh_set(gen, noise_lat, [f"noise_{i:03d}" for i in range(n_gen)],
                               RUNS / "noise", args.resolution)
    # the same training subsets for the meshes and their decodings
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
    return sampled, gen_names, gen_meshes, sets


def main():
    args = parse_args()
    bench = Bench("generate")  # timings need an idle machine: its load is recorded

    import torch
    import trimesh

    torch.set_num_threads(args.threads)

    from ngc_gen.app.runtime.config import repo_root
    from ngc_gen.data.datasets import Creatures
    from ngc_gen.eval import pairwise_chamfer
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
    sampled, gen_names, gen_meshes, sets = sample_sets(gen, args, train_meshes, n_ref, split)

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
    score(sets, ref, d_rr, args.points, res)
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
    path = bench.write(res)
    print("\n" + table(json.loads(path.read_text())))
    print(f"total {res['timing']['total_s'] / 60:.1f} min; results in {RESULTS}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(res: dict) -> str:
    rows = [("generated", "generated (EDM, 18 Heun steps)"),
            ("train_recon", "training latents, decoded (decoder ceiling)"),
            ("train_set", "training meshes (ceiling)"),
            ("train_decoded", "training latents decoded (the shape-latent model's ceiling)"),
            ("noise", "noise latents N(mean, std), no diffusion (floor)")]
    lines = ["| shapes vs held-out | MMD-CD (x1e-3) | COV-CD (%) | 1-NNA-CD (%) | sets |",
             "|---|---|---|---|---|"]
    for key, label in rows:
        if key in res:
            m, per = res[key], res["per_set"][key]
            rng = lambda k, f: (f" ({f * min(p[k] for p in per):.0f}-"  # noqa: E731
                                f"{f * max(p[k] for p in per):.0f})" if len(per) > 1 else "")
            lines.append(f"| {label} | {1e3 * m['mmd_cd']:.3f} | {100 * m['cov_cd']:.1f}"
                         f"{rng('cov_cd', 100)} | {100 * m['nna_cd']:.1f}{rng('nna_cd', 100)} | "
                         f"{len(per)} |")
    t = res["timing"]
    lines += ["", f"{res['n_reference']} held-out creatures as the reference, {res['n_train']} "
                  f"training creatures; shape latents {res['shape_latent_steps']} steps, "
                  f"diffusion {res['diffusion_steps']} steps; sampling per shape: latent "
                  f"{1e3 * t['latent_s_per_shape']:.0f} ms, mesh at {res['resolution']}^3 "
                  f"{t['mesh_s_per_shape']:.2f} s ({res.get('threads', 1)} torch threads). "
                  f"Targets: 1-NNA <= 65%, COV >= 50%."]
    return "\n".join(lines)


def headline(r):
    g, t = r["generated"], r["train_set"]
    return (f"MMD-CD {sci(g['mmd_cd'])}, COV {pct(g['cov_cd'], 1)}, 1-NNA {pct(g['nna_cd'], 1)} "
            f"(training meshes {sci(t['mmd_cd'])}, {pct(t['cov_cd'], 1)}, {pct(t['nna_cd'], 1)})")


if __name__ == "__main__":
    main()
