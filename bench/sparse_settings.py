"""The sparse extractor's settings: evaluations, exactness and time of each.

    python -m bench.sparse_settings [--variants band:track=false track track_near0:track_near=0
                                     track_c1:lipschitz=1.0] [--resolutions 128 256] [--repeats 4]

A variant is `label[:key=value,...]` over `SparseSettings` fields (the rest at their defaults):
`lipschitz` = c keeps a block while |f| <= c x its size (c >= 1: a true SDF's bound, the default
1.5 adds a safety margin for fitted fields); `track` = the last level visits only blocks whose
corners cross or come within `track_near` x c x the grid spacing of the band, and the surface
grows from them (false: every block the margin keeps).
Per fitted shape and resolution, for each variant: the network evaluations of the sparse path and
whether its mesh equals the prefiltered reference bit for bit. Shapes: bench/deform.py's fit (bar,
creature_0000, ant) and every fit of bench/autogc.py in its fit cache (6 shapes each; the latest of
each method and seed), whatever has been trained. Time: the creature at the highest resolution
extracted with each variant in turn, `--repeats` rounds interleaved in this process (a shared
machine drifts between runs), best and median. Writes bench/results/sparse_settings.json ({machine,
settings, cases: [{fit, shape, n_gcs, resolution, evals: {label: n}, identical: {label: bool},
cd: {label: Chamfer to the prefiltered mesh, DeepSDF convention against its surface, 0 where
identical}}], timing: {label: {best_s, median_s, runs_s}}, summary: {label: {identical, cases,
cd_max, evals_over_first_min/max, median_time_over_first}}}); ratios are against the first
variant.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from bench._harness import Bench, FitCache, latest_fit
from bench._tables import rows_table


def same_mesh(a, b) -> bool:
    import numpy as np

    return bool(np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces))


def parse_variant(text: str):
    """'label:key=value,...' -> (label, SparseSettings kwargs); values are numbers or booleans."""
    label, _, rest = text.partition(":")
    kwargs = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        low = value.strip().lower()
        kwargs[key.strip()] = (low == "true") if low in ("true", "false") else float(value)
    return label, kwargs


def timed(settings: dict, gcs, rows, args) -> dict:
    """Each variant's seconds on one shape at the largest resolution, the variants
    interleaved `--repeats` times (all see the same drift of the machine's load)."""
    import numpy as np

    from ngc_gen.extract import extract_mesh

    R = max(args.resolutions)
    extract_mesh(gcs, rows, R)                                       # warm-up
    runs = {c: [] for c in settings}
    for _ in range(args.repeats):
        for c, st in settings.items():
            t0 = time.perf_counter()
            extract_mesh(gcs, rows, R, settings=st)
            runs[c].append(time.perf_counter() - t0)
    timing = {}
    for c, ts in runs.items():
        timing[c] = {"best_s": min(ts), "median_s": float(np.median(ts)), "runs_s": ts,
                     "resolution": R, "shape": "creature_0000 (deform fit)"}
        print(f"creature_0000 R={R} {c}: best {min(ts):.3f} s, median "
              f"{np.median(ts):.3f} s ({args.repeats} runs, interleaved)")
    return timing


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", nargs="+",
                    default=["band:track=false", "track", "track_near0:track_near=0",
                             "track_c1:lipschitz=1.0"],
                    help="label[:key=value,...] over SparseSettings; ratios against the first")
    ap.add_argument("--resolutions", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--repeats", type=int, default=4)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    return ap.parse_args()


def main():
    args = parse_args()
    bench = Bench("sparse_settings")

    import torch

    from ngc_gen.eval import mesh_chamfer
    from ngc_gen.extract import SparseSettings, extract_mesh
    from ngc_gen.lit.checkpoint import load_autodecoder
    from ngc_gen.shape import shapes_from_autodecoder

    torch.set_num_threads(args.threads)
    deform = latest_fit("deform", {"trainer.max_steps": 1500})    # bench/deform.py's fit
    fits = {"deform": deform.run_dir / "checkpoints/last.ckpt"}
    for f in FitCache("autogc").entries():          # oldest first: the latest of a label wins
        if (f.run_dir / "checkpoints/last.ckpt").exists():
            fits[f"autogc/{f.info['label']}"] = f.run_dir / "checkpoints/last.ckpt"
    fits = dict(sorted(fits.items(), key=lambda kv: (kv[0] != "deform", kv[0])))
    specs = dict(parse_variant(v) for v in args.variants)
    settings = {label: SparseSettings.from_yaml(**kw) for label, kw in specs.items()}
    cases, timing_input = [], None
    for fit_name, ckpt in fits.items():
        module = load_autodecoder(ckpt)
        for name, shape in shapes_from_autodecoder(module).items():
            gcs, rows = shape.gcs, shape.rows
            if fit_name == "deform" and name == "creature_0000":
                timing_input = (gcs, rows)
            for R in args.resolutions:
                ref = extract_mesh(gcs, rows, R, method="prefiltered").mesh
                case = {"fit": fit_name, "shape": name, "n_gcs": len(gcs), "resolution": R,
                        "evals": {}, "identical": {}, "cd": {}}
                for c, st in settings.items():
                    res = extract_mesh(gcs, rows, R, settings=st)
                    case["evals"][c] = int(res.stats["n_network_evals"])
                    case["identical"][c] = same_mesh(res.mesh, ref)
                    case["cd"][c] = 0.0 if case["identical"][c] else mesh_chamfer(res.mesh, ref)
                cases.append(case)
                print(f"{fit_name:26s} {name:14s} R={R:3d} " + "  ".join(
                    f"{c}: {case['evals'][c]:>7,d} evals, identical {case['identical'][c]}"
                    + ("" if case["identical"][c] else f" (CD {case['cd'][c]:.1e})")
                    for c in settings), flush=True)

    timing = {} if timing_input is None else timed(settings, *timing_input, args)
    base = next(iter(settings))
    summary = {c: {"identical": sum(x["identical"][c] for x in cases),
                        "cases": len(cases),
                        "cd_max": max(x["cd"][c] for x in cases),
                        "evals_over_first_min": min(x["evals"][c] / x["evals"][base]
                                                    for x in cases),
                        "evals_over_first_max": max(x["evals"][c] / x["evals"][base]
                                                    for x in cases)}
               for c in settings}
    if timing:
        for c in settings:
            summary[c]["median_time_over_first"] = \
                timing[c]["median_s"] / timing[base]["median_s"]
    for c, s in summary.items():
        print(f"{c}: {s['identical']} of {s['cases']} meshes identical to prefiltered (largest "
              f"CD {s['cd_max']:.1e}); "
              f"evaluations {s['evals_over_first_min']:.2f}-{s['evals_over_first_max']:.2f}x "
              f"{base}'s" + (f"; median time {s['median_time_over_first']:.2f}x" if timing
                               else ""))
    res = {"settings": {"variants": {k: dataclasses.asdict(v) for k, v in settings.items()},
                        "resolutions": args.resolutions, "repeats": args.repeats,
                        "fits": {k: os.path.relpath(v, ROOT) for k, v in fits.items()}},
           "cases": cases, "timing": timing, "summary": summary}
    print(f"wrote {bench.write(res)}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
    variants = r["settings"]["variants"]
    varying = [k for k in next(iter(variants.values()))
               if len({json.dumps(v[k]) for v in variants.values()}) > 1]
    base = next(iter(variants))
    rows = []
    for label, s in r["summary"].items():
        t = r["timing"].get(label)
        time_s = (f"{t['median_s']:.2f} ({s['median_time_over_first']:.2f}x)" if t else "-")
        ident = f"{s['identical']} of {s['cases']}" + (
            f" (largest CD {s['cd_max']:.1e})" if s["identical"] < s["cases"] else "")
        rows.append([f"`{label}`: " + ", ".join(f"{k}={variants[label][k]}" for k in varying),
                     ident, f"{s['evals_over_first_min']:.2f}-{s['evals_over_first_max']:.2f}",
                     time_s])
    t0 = next(iter(r["timing"].values()), None)
    timed = f"{t0['shape']} at {t0['resolution']}, median of {len(t0['runs_s'])}" if t0 else "-"
    fits = sorted({c["fit"] for c in r["cases"]})
    lines = rows_table(["settings", "meshes identical to prefiltered",
                        f"evaluations vs `{base}`", f"time (s), {timed}"], rows)
    lines += ["", f"{len(r['cases'])} meshes: {len({(c['fit'], c['shape']) for c in r['cases']})}"
                  f" fitted shapes of {len(fits)} fits ({', '.join(fits)}) at "
                  f"{', '.join(map(str, r['settings']['resolutions']))}."]
    return "\n".join(lines)


def headline(r):
    t = r["summary"]["track"]
    return f"default settings: {t['identical']} of {t['cases']} fitted meshes identical to the reference"


if __name__ == "__main__":
    main()
