"""Animals benchmark: rigged quadrupeds become GCs (coverage, purity), their rest poses are fitted
(F-score), and the generator trained on posed animals is measured against held-out clips and,
separately, held-out species, each beside its ceiling and floor, with memorisation and a
wolf -> horse interpolation.

    python -m bench.animals [--frames 2] [--fit-steps N] [--shape-latent-steps N]
                            [--diffusion-steps N] [--sets 2] [--resolution 128]

Data: data=animals with `--frames` frames per clip (the default config has 5; the bench's
size is in `recipe`). Rows (2048 surface points per shape, squared Chamfer, every mesh in the
data's normalised frame: bounding box centred, longest side 1.6; each the mean over sets of as
many shapes as the reference):
  generated   EDM samples (Heun, 18 steps) decoded to GCs + codes, meshed at --resolution
  generated_churn  the same with the stochastic sampler (CHURN: 40 steps, S_churn 40)
  train_set   the ceiling: training meshes (random subsets)
  noise       the floor: latents ~ N(mean, std^2) per dimension of the trained latents
  train_decoded  the training latents themselves decoded and meshed like the samples (random
              subsets, no latent twice): what a generator that reproduced its latents exactly,
              and never the same one twice, would score
References: `clips` = training species at their held-out clips (data.heldout_clips_by_species:
3 per species, rotated so every clip stays in training for other species), `species` =
held-out species at every clip. nearest_train_cd_median: the median over generated shapes of the Chamfer distance
to the nearest training mesh. interp_max_over_mean: along wolf -> horse (8 steps, training
latents), the largest consecutive-step Chamfer over their mean. purity, coverage: over every
built shape (train, test and rest). fit_fscore_min: the 12 rest poses, each fitted on its own
with its template GCs (train.py stage=fit data.species=[s], the default recipe unless
--fit-steps; `--fit-workers` side by side), F-score@0.01.

Writes bench/results/animals.json and animals.png (fitted, posed and generated animals).
Trained runs are kept in the bench's fit cache (bench/_harness.py).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bench._generation import clouds, mesh_set, rows_for
from bench._harness import (Bench, FitCache, cached_stage, config_recipe, dataset_identity,
                            train_subprocess)
from bench._tables import pct

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "bench/runs/animals"
RESULTS = ROOT / "bench/results"
CHURN = {"steps": 40, "churn": 40, "S_min": 0.05, "S_max": 50, "S_noise": 1.003}  # sample.py
                  # sampler=... for the stochastic EDM sampler (NVlabs/edm's settings style)
REST_FRAMES = 2   # the rest poses do not depend on the frames per clip: fitted from one build,
                  # so a run at another --frames reuses the cached rest-pose fits


def data_overrides(args) -> list[str]:
    return ["data=animals", f"data.frames={args.frames}", "trainer.enable_progress_bar=false",
            "logger=csv", f"seed={args.seed}"]


def rest_fits(cache: FitCache, args) -> list:
    """Each species' rest pose fitted on its own (train.py stage=fit data.split=rest
    data.species=[s], the default recipe unless --fit-steps), as a user fits one asset; the fits
    run in `--fit-workers` processes of one thread and are cached like the other stages."""
    from concurrent.futures import ThreadPoolExecutor

    from ngc_gen.app.runtime.config import compose_config

    species = list(compose_config(overrides=data_overrides(args)).data.species)

    def one(s: str):
        over = ["stage=fit", *data_overrides(args), f"data.frames={REST_FRAMES}",
                "data.split=rest", f"data.species=[{s}]",
                "data.heldout_species=[]", "data.heldout_clips_by_species=null",
                "prepare.cache_dir=${paths.cache_dir}/prepared/animals_rest",
                *([f"trainer.max_steps={args.fit_steps}"] if args.fit_steps else [])]
        cfg = compose_config(overrides=over)

        def fit(run_dir: Path) -> dict:
            return {"stage_s": train_subprocess(over, run_dir, f"the rest-pose fit of {s}")}

        f = cache.get({"stage": "fit_rest", "config": config_recipe(cfg),
                       "data": dataset_identity(cfg)}, fit, refit=args.refit)
        print(f"rest pose of {s} fitted{' (cached)' if f.reused else ''}: {f.run_dir}",
              flush=True)
        return f

    with ThreadPoolExecutor(max(1, args.fit_workers)) as pool:
        return list(pool.map(one, species))


def train(args) -> dict:
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.train_diffusion import run_diffusion
    from ngc_gen.app.stages.train_shape_latent import run_shape_latent

    cache = FitCache("animals")
    base = ["experiment=animals", *data_overrides(args)]
    fits = rest_fits(cache, args)
    sl = cached_stage(cache, "shape_latent", compose_config(overrides=[
        *base, "stage=shape_latent", "shape_latent.preview=0",
        *([f"shape_latent.max_steps={args.shape_latent_steps}"] if args.shape_latent_steps
          else [])]), run_shape_latent, args.refit, RUNS / "shape_latent",
        leave_out=("diffusion",))
    diff = cached_stage(cache, "diffusion", compose_config(overrides=[
        *base, "stage=diffusion", f"shape_latent_run={sl.run_dir}",
        *([f"diffusion.max_steps={args.diffusion_steps}"] if args.diffusion_steps else [])]),
        run_diffusion, args.refit, RUNS / "diffusion")
    load = lambda f: json.loads((f.run_dir / "metrics.json").read_text())  # noqa: E731
    shapes = {n: {**m, "mesh": str(f.run_dir / "meshes" / f"{n}.ply")}
              for f in fits for n, m in load(f)["shapes"].items()}
    return {"fit": {"shapes": shapes, "steps": load(fits[0])["steps"]}, "shape_latent": load(sl),
            "shape_latent_dir": sl.run_dir, "diffusion": load(diff), "diffusion_dir": diff.run_dir}


def picture(fitted: dict, rest: list[dict], posed: list[dict], gen_dir: Path, gen_names,
            path: Path) -> None:
    """Rows: rest poses fitted (the fitted NGC mesh), posed training animals with their GCs,
    generated animals with their decoded GCs."""
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.viz import gcs_surface, render_grid, render_or_warn

    def with_gcs(mesh_path, ann_path):
        return (trimesh.load(mesh_path, process=False), gcs_surface(load_annotation(ann_path).gcs))

    rows = [[trimesh.load(fitted[r["name"]]["mesh"], process=False) for r in rest],
            [with_gcs(r["mesh"], r["annotation"]) for r in posed],
            [with_gcs(gen_dir / f"{n}.ply", gen_dir / f"{n}.yaml") for n in gen_names]]
    titles = [[r["name"] for r in rest], [r["name"] for r in posed], list(gen_names)]
    render_or_warn(render_grid, path, rows, labels=["fitted (rest)", "posed + GCs",
                                                    "generated + GCs"],
                   titles=titles, up="y")


def sample_sets(gen, n_gen: int, args):
    """n_gen meshes of each row: generated (deterministic and stochastic sampler), noise
    latents, training latents decoded. -> (generated names, and the four lists of meshes)."""
    import numpy as np
    import trimesh

    from ngc_gen.app.stages.sample import generate

    sampled = generate(gen, RUNS / "samples", n=n_gen, seed=args.seed,
                       resolution=args.resolution, progress=False)
    gen_names = sorted(sampled["shapes"])
    gen_m = [trimesh.load(RUNS / "samples" / f"{n}.ply", process=False) for n in gen_names]
    churned = generate(gen, RUNS / "samples_churn", n=n_gen, seed=args.seed,
                       resolution=args.resolution, progress=False, sampler=CHURN)
    churn_m = [trimesh.load(RUNS / "samples_churn" / f"{n}.ply", process=False)
               for n in sorted(churned["shapes"])]
    noise_m, _ = mesh_set(gen, gen.noise_latents(n_gen, seed=args.seed + 1, kind="fitted"),
                          [f"noise_{i:03d}" for i in range(n_gen)], RUNS / "noise",
                          args.resolution)
    pick = np.random.default_rng(args.seed + 2).choice(   # its own draws: main's subsets stay
        len(gen.train_latents), n_gen, replace=n_gen > len(gen.train_latents))
    decoded_m, _ = mesh_set(gen, gen.train_latents[pick], [f"train_{i:03d}" for i in pick],
                            RUNS / "train_decoded", args.resolution)
    return gen_names, gen_m, churn_m, noise_m, decoded_m


def interpolation(gen, train: list[dict], args):
    """A wolf interpolated into the horse of the same clip in 8 steps: (a, b, the largest
    consecutive-step Chamfer over their mean (None if a mesh is empty), empty meshes)."""
    import numpy as np
    import trimesh

    from ngc_gen.app.stages.sample import interpolate
    from ngc_gen.eval import pairwise_chamfer

    a = next(r["name"] for r in train if r["species"] == "wolf")
    b = next(r["name"] for r in train if r["species"] == "horse" and
             r["clip"] == next(x for x in train if x["name"] == a)["clip"])
    interpolate(gen, RUNS / "interp", a=a, b=b, steps=8, resolution=args.resolution,
                progress=False)
    inter_m = [trimesh.load(p, process=False) for p in sorted((RUNS / "interp").glob("*.ply"))]
    i_pts, empty = clouds(inter_m, args.points, 0)
    steps = np.array([pairwise_chamfer(i_pts[i:i + 1], i_pts[i + 1:i + 2])[0, 0]
                      for i in range(len(i_pts) - 1)])
    return a, b, (float(steps.max() / steps.mean()) if empty == 0 else None), empty


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=5, help="frames per clip (the config's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fit-steps", type=int, default=None, help="default: the fit recipe's")
    ap.add_argument("--shape-latent-steps", type=int, default=None,
                    help="default: conf/experiment/animals.yaml's")
    ap.add_argument("--diffusion-steps", type=int, default=None,
                    help="default: conf/experiment/animals.yaml's")
    ap.add_argument("--sets", type=int, default=2, help="sets of n_reference generated shapes")
    ap.add_argument("--train-subsets", type=int, default=10)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--points", type=int, default=2048)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--fit-workers", type=int, default=2,
                    help="processes fitting the rest poses side by side")
    ap.add_argument("--refit", action="store_true")
    return ap.parse_args()


def main():
    import numpy as np

    args = parse_args()
    bench = Bench("animals")

    import torch
    import trimesh
    from hydra.utils import instantiate

    torch.set_num_threads(args.threads)
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.data.rigs.animals import purity_summary
    from ngc_gen.eval import pairwise_chamfer
    from ngc_gen.generate import load_generator

    t_start = time.perf_counter()
    data = instantiate(compose_config(overrides=data_overrides(args)).data)
    records = {}
    for split in ("train", "test_clips", "test_species", "rest"):
        data.split = split
        records[split] = data.build()
    load = lambda rs: [trimesh.load(r["mesh"], process=False) for r in rs]  # noqa: E731
    train_m, clips_m, species_m = (load(records[s]) for s in ("train", "test_clips",
                                                              "test_species"))
    print(f"{len(train_m)} training / {len(clips_m)} held-out-clip / {len(species_m)} "
          f"held-out-species animals")

    runs = train(args)
    gen = load_generator(runs["diffusion_dir"])
    n_ref = max(len(clips_m), len(species_m))
    n_gen = args.sets * n_ref
    gen_names, gen_m, churn_m, noise_m, decoded_m = sample_sets(gen, n_gen, args)
    rng = np.random.default_rng(args.seed)
    res = {"n_train": len(train_m), "n_heldout_clips": len(clips_m),
           "n_heldout_species": len(species_m)}
    for key, ref_m in (("clips", clips_m), ("species", species_m)):
        k = len(ref_m)
        subsets = [rng.choice(len(train_m), k, replace=False) for _ in range(args.train_subsets)]
        res[key] = rows_for({"generated": [gen_m[i:i + k] for i in range(0, args.sets * k, k)],
                             "generated_churn": [churn_m[i:i + k]
                                                 for i in range(0, args.sets * k, k)],
                             "train_set": [[train_m[i] for i in s] for s in subsets],
                             "noise": [noise_m[i:i + k] for i in range(0, args.sets * k, k)],
                             "train_decoded": [decoded_m[i:i + k]
                                               for i in range(0, args.sets * k, k)]},
                            ref_m, args.points)
    g_pts, _ = clouds(gen_m, args.points, 0)
    t_pts, _ = clouds(train_m, args.points, 0)
    res["nearest_train_cd_median"] = float(np.median(pairwise_chamfer(g_pts, t_pts).min(1)))
    a, b, res["interp_max_over_mean"], empty = interpolation(gen, records["train"], args)
    built = records["train"] + records["test_clips"] + records["test_species"] + records["rest"]
    res.update(purity_summary(built))
    res["fit_fscore_min"] = float(min(m["fscore"] for m in runs["fit"]["shapes"].values()))
    res["recipe"] = {
        "frames": args.frames, "fit_steps": runs["fit"]["steps"],
        "shape_latent_steps": runs["shape_latent"]["steps"],
        "diffusion_steps": runs["diffusion"]["steps"],
        "diffusion_batch": runs["diffusion"].get("batch_size"),
        "diffusion_space_dim": runs["diffusion"].get("space_dim"),
        "diffusion_pca_complete": runs["diffusion"].get("pca_complete"),
        "diffusion_transferred": runs["diffusion"].get("n_transferred", 0), "sets": args.sets,
        "train_subsets": args.train_subsets, "resolution": args.resolution,
        "points": args.points, "interp": [a, b], "interp_empty_meshes": int(empty),
        "fit_fscore": {n: m["fscore"] for n, m in runs["fit"]["shapes"].items()},
        "fit": "each species' rest pose on its own",
        "total_s": time.perf_counter() - t_start}
    show = [r for r in records["train"] if r["frame"] == 0][::9][:4]
    picture(runs["fit"]["shapes"], records["rest"][::3][:4], show, RUNS / "samples", gen_names[:4],
            RESULTS / "animals.png")
    path = bench.write(res)
    print("\n" + table(json.loads(path.read_text())))
    print(f"total {res['recipe']['total_s'] / 60:.1f} min; results in {RESULTS}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
    rows = [("generated", "generated (EDM, 18 Heun steps)"),
            ("generated_churn", "generated (EDM, stochastic: 40 steps, S_churn 40)"),
            ("train_set", "training meshes (ceiling)"),
            ("train_decoded", "training latents decoded (the shape-latent model's ceiling)"),
            ("noise", "noise latents N(mean, std), no diffusion (floor)")]
    rows = [(k, label) for k, label in rows if k in r["clips"]]
    lines = []
    for key, title in (("clips", f"{r['n_heldout_clips']} shapes of training species at held-out clips"),
                       ("species", f"{r['n_heldout_species']} shapes of held-out species")):
        lines += [f"| vs {title} | MMD-CD (x1e-3) | COV-CD (%) | 1-NNA-CD (%) |", "|---|---|---|---|"]
        lines += [f"| {label} | {1e3 * r[key][k]['mmd_cd']:.3f} | {100 * r[key][k]['cov_cd']:.1f} | "
                  f"{100 * r[key][k]['nna_cd']:.1f} |" for k, label in rows]
        lines.append("")
    rc = r["recipe"]
    interp = r["interp_max_over_mean"]
    lines += [f"{r['n_train']} training animals ({rc['frames']} frames per clip); fit of the rest "
              f"poses {rc['fit_steps']} steps, shape latents {rc['shape_latent_steps']}, diffusion "
              f"{rc['diffusion_steps']}" + (f" (batches of {rc['diffusion_batch']})"
                                            if rc.get("diffusion_batch") else "")
              + (f" on {rc['diffusion_space_dim']} principal axes of the "
              f"latents" if rc.get("diffusion_space_dim") else "")
              + (" (the others from the nearest training latent)"
                 if rc.get("diffusion_pca_complete") == "nearest" else "")
              + (f", trained on the training latents and {rc['diffusion_transferred']} pose-transferred "
                 f"ones" if rc.get("diffusion_transferred") else "")
              + (f". Generated rows: {rc['sets']} set{'s' if rc['sets'] > 1 else ''} of as many shapes as "
                 f"the reference; ceiling: {rc['train_subsets']} training subsets" if rc.get("sets") else "")
              + ". Memorisation: median Chamfer from a generated animal to its "
              f"nearest training animal {1e3 * r['nearest_train_cd_median']:.3f} x1e-3. "
              f"{rc['interp'][0]} -> {rc['interp'][1]}: largest consecutive-step Chamfer "
              + (f"{interp:.2f} x their mean" if interp is not None else "undefined (an empty mesh)")
              + f". GCs on {r['n_train'] + r['n_heldout_clips'] + r['n_heldout_species'] + 12} "
              f"posed meshes: coverage >= {r['coverage_min']:.5f}, purity mean "
              f"{100 * r['purity_mean']:.2f}%, worst {100 * r['purity_worst']:.2f}%; rest-pose fits "
              f"({rc.get('fit', 'the 12 in one run')}) F-score@0.01 >= {r['fit_fscore_min']:.3f}."]
    return "\n".join(lines)


def headline(r):
    c = r["clips"]
    return (f"{r['n_train']} posed animals: vs held-out clips 1-NNA {pct(c['generated']['nna_cd'], 1)}"
            f" (ceiling {pct(c['train_set']['nna_cd'], 1)}, floor {pct(c['noise']['nna_cd'], 1)});"
            f" rig GCs purity >= {pct(r['purity_worst'], 1)}; rest-pose fits F >= "
            f"{r['fit_fscore_min']:.3f}")


if __name__ == "__main__":
    main()
