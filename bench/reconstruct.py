"""Reconstruction into a trained model vs a direct fit (issue: "a held-out creature reconstructed
into the creature shape-latent model lands within 2x of the CD of the same shape fitted directly").

    python -m bench.reconstruct [--shape-latent-run RUN] [--limit 4] [--refit]

- direct: `train.py stage=fit data=creatures data.split=test` (the demo's fit recipe: small
  preset, 1500 steps), the held-out creatures fitted with their own codes and a trained decoder;
- reconstructed: `train.py experiment=generate stage=reconstruct run=<shape-latent run>
  data.split=test`: one latent per held-out creature, every network weight frozen (the run the
  generation bench trains on the 48 training creatures, from its fit cache or trained now;
  `--shape-latent-run` to use another),
  then the per-GC codes it decodes to refined (reconstruct.refine_steps, decoders still frozen),
  meshed with the shapes' own GCs (reconstruct.gcs=input); for comparison the latent alone
  (refine_steps=0), and the latent alone with the GCs it decodes to (reconstruct.gcs=decoded).
Both meshed at the same resolution and scored with the same Chamfer (30k points each way,
squared, means summed). Every run is kept in the bench's fit cache (.cache/bench/fits/
reconstruct), keyed by its whole config, the held-out shapes' data and (for the reconstructions)
the shape-latent checkpoint's bytes; --refit runs them again. Writes
bench/results/reconstruct.json {shapes, direct, reconstructed, reconstructed_latent_only,
reconstructed_decoded_gcs, ratio, ratio_latent_only, ratio_decoded_gcs, settings, machine}
(bench/_harness.py).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bench._generation import recipe_args, train
from bench._harness import (Bench, FitCache, cached_run_fit, config_recipe,
                            dataset_identity, file_identity)
from bench._tables import rows_table, span

ROOT = Path(__file__).resolve().parents[1]

def common(args) -> list[str]:
    return ["data=creatures", "data.split=test", f"data.limit={args.limit}",
            f"extract.resolution={args.resolution}", "trainer.enable_progress_bar=false",
            "logger=csv", "prepare.n_samples=50000",
            f"prepare.cache_dir={ROOT}/.cache/prepared/creatures_gen50k_heldout"]


def direct(args) -> dict:
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=common(args) + [
        "stage=fit", "model=small", f"trainer.max_steps={args.fit_steps}"])
    f = cached_run_fit("reconstruct", cfg, refit=args.refit, label="direct")
    return json.loads((f.run_dir / "metrics.json").read_text())


# result key -> (run name, overrides): the default (latent, then its codes refined, the input's
# GCs), the latent alone, and the latent alone meshed with the GCs it decodes to
VARIANTS = {
    "reconstructed": ("reconstruct_refined", ["reconstruct.gcs=input"]),
    "reconstructed_latent_only": ("reconstruct_input", ["reconstruct.gcs=input",
                                                        "reconstruct.refine_steps=0"]),
    "reconstructed_decoded_gcs": ("reconstruct_decoded", ["reconstruct.gcs=decoded"]),
}


def reconstructed(args, name: str, overrides: list[str]) -> dict:
    from omegaconf import open_dict

    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.registry import run_stage

    cfg = compose_config(overrides=["experiment=generate"] + common(args) + [
        "stage=reconstruct", f"run={args.shape_latent_run}", *overrides])

    def fit(run_dir: Path) -> dict:
        with open_dict(cfg):
            cfg.run_dir = str(run_dir)
        run_stage(cfg)
        return {"label": name}

    recipe = {"config": config_recipe(cfg), "data": dataset_identity(cfg),
              "shape_latent": file_identity([args.shape_latent_run / "checkpoints/last.ckpt"])}
    f = FitCache("reconstruct").get(recipe, fit, refit=args.refit)
    return json.loads((f.run_dir / "metrics.json").read_text())


def default_shape_latent_run() -> Path:
    """bench/generate.py's shape-latent run at its default recipe (the generate bench's fit
    cache)."""
    ap = argparse.ArgumentParser()
    recipe_args(ap)
    return train(ap.parse_args([]))["shape_latent_dir"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shape-latent-run", type=Path, default=None,
                    help="default: bench/generate.py's run (its fit cache; trained if absent)")
    ap.add_argument("--limit", type=int, default=4, help="held-out creatures")
    ap.add_argument("--fit-steps", type=int, default=1500)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--threads", default="auto")
    ap.add_argument("--refit", action="store_true", help="run the fits again even if cached")
    ap.add_argument("--only", choices=["direct", "reconstruct"], default=None)
    args = ap.parse_args()
    bench = Bench("reconstruct")
    from ngc_gen.app.runtime.cli import set_threads

    threads = set_threads(args.threads)
    t0 = time.perf_counter()
    if args.only != "direct" and args.shape_latent_run is None:
        args.shape_latent_run = default_shape_latent_run()
    res = {}
    if args.only in (None, "direct"):
        d = direct(args)
        res["direct"] = {n: m["cd"] for n, m in d["shapes"].items()}
    if args.only in (None, "reconstruct"):
        for key, (name, overrides) in VARIANTS.items():
            r = reconstructed(args, name, overrides)
            res[key] = {n: m["cd"] for n, m in r["shapes"].items()}
            res[f"{key}_steps"] = r.get("steps")
            res[f"{key}_refine_steps"] = r.get("refine_steps", 0)
    path = bench.path
    if args.only and path.exists():  # keep the other half of an earlier run
        res = {**json.loads(path.read_text()), **res}
        res.pop("machine", None)
    if {"direct", "reconstructed"} <= set(res):
        names = sorted(res["direct"])
        res["shapes"] = names
        for key, out in (("reconstructed", "ratio"), ("reconstructed_latent_only",
                                                      "ratio_latent_only"),
                         ("reconstructed_decoded_gcs", "ratio_decoded_gcs")):
            if key in res:
                ratios = [res[key][n] / res["direct"][n] for n in names]
                res[out] = {"per_shape": dict(zip(names, ratios)),
                            "mean": sum(ratios) / len(ratios), "max": max(ratios)}
    res["settings"] = {"limit": args.limit, "fit_steps": args.fit_steps,
                       "resolution": args.resolution, "shape_latent_run": str(
                           args.shape_latent_run), "threads": threads,
                       "seconds": time.perf_counter() - t0}
    bench.write(res)
    for key in ("ratio", "ratio_latent_only", "ratio_decoded_gcs"):
        if key in res:
            print(f"{key}: CD reconstructed / CD direct fit, mean {res[key]['mean']:.2f}, "
                  f"max {res[key]['max']:.2f} over {len(res['shapes'])} held-out creatures")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
    rows = []
    for key, label in (("ratio", "latent, then its codes refined (the default)"),
                       ("ratio_latent_only", "latent alone"),
                       ("ratio_decoded_gcs", "latent alone, meshed with the GCs it decodes to")):
        if key in r:
            per = list(r[key]["per_shape"].values())
            rows.append([label, f"{r[key]['mean']:.2f}x ({span(per)}x)"])
    lines = rows_table(["into the generation recipe's shape-latent model", "CD / direct fit's CD,"
                        " mean (range)"], rows)
    direct = list(r["direct"].values())
    s = r["settings"]
    lines += ["", f"{len(r['shapes'])} held-out creatures ({', '.join(r['shapes'])}), meshes at "
                  f"{s['resolution']}^3; direct fit {s['fit_steps']} steps, CD "
                  f"{span([1e5 * d for d in direct], '.1f')}e-5; latent "
                  f"{r.get('reconstructed_steps')} steps, codes "
                  f"{r.get('reconstructed_refine_steps')} steps; {s['seconds']:.0f} s in all."]
    return "\n".join(lines)


def headline(r):
    return f"held-out creatures into the generator: CD {r['ratio']['mean']:.2f}x a direct fit"


if __name__ == "__main__":
    main()
