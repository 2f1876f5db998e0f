"""Extraction benchmark: dense, prefiltered and sparse extraction of fitted shapes (issue 10).

    python bench/extract.py [--resolutions 128 256 512] [--dense-max-evals 4e7] [--threads 2]

Shapes: the deformation bench's fit (bench/deform.py: a one-GC square bar, creature_0000 with 10
GCs and the ant with 15 GCs, small preset, 1500 steps; trained once into bench/runs/deform if
absent). Per shape and resolution R (grid over [-1, 1]^3):
- dense: the network at every grid point of the box for every GC, dense_evals = R^3 x n_gcs.
  Timed where dense_evals <= --dense-max-evals; elsewhere dense_s is the same shape's seconds
  per evaluation (timed at --dense-rate-resolution) times dense_evals, and the case says
  `dense_s_extrapolated: true`.
- prefiltered: the network at the grid points inside each GC (the previous default path).
- sparse: the default multi-level path (`ngc_gen.extract`), timed after a warm-up run.
- cd_sparse_vs_prefiltered: Chamfer distance between the two meshes, DeepSDF convention (30k
  surface samples each way, squared distances, mean each way, summed).
- incremental_s / incremental_evals: a FieldCache re-extraction after one GC changed (a leg's
  radii, or the bar's, scaled by 1.1), against full_after_edit_s from scratch (resolutions up
  to --incremental-max-resolution).
Wall times with --threads torch (and numba) threads; the 1-minute load average at start and end
is recorded, since the machine may be shared. Writes bench/results/extract.json
({machine, settings, cases: [{shape, resolution, dense_evals, prefiltered_evals, sparse_evals,
dense_s, prefiltered_s, sparse_s, cd_sparse_vs_prefiltered, ...}], targets}).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

SHAPES = {"bar": "bar", "creature": "creature_0000", "ant": "ant"}   # label -> fitted name
EDITED_GC = {"bar": "bar", "creature": "leg_fl", "ant": "leg_l1"}
TARGET_R = 256


def chamfer(a, b, n: int = 30000, seed: int = 0) -> float:
    from ngc_gen.eval.fitting import chamfer as cd
    from ngc_gen.eval.sampling import sample_surface

    return float(cd(sample_surface(a, n, seed)[0], sample_surface(b, n, seed)[0]))


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def gc_key(gc, code) -> tuple:
    return (repr(gc.to_dict()), code.detach().numpy().tobytes())


def scaled(gc, factor: float):
    from ngc_gen.geometry import Key

    return gc.replace(keys=[Key(k.t, tuple(factor * r for r in k.radii), k.twist)
                            for k in gc.keys])


def run_shape(label: str, module, resolutions, dense_max_evals: float, rate_resolution: int,
              incremental_max: int) -> list[dict]:
    from ngc_gen.extract import FieldCache, extract_mesh
    from ngc_gen.shape import Shape, recorded_gcs

    meta = next(m for m in module.hparams.meta["shapes"] if m["name"] == SHAPES[label])
    gcs = recorded_gcs(meta)
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]]
    codes = codes.detach()
    fn = Shape(gcs, codes, module.decoder).rows
    extract_mesh(gcs, fn, 64)                       # warm-up: JIT caches, allocator
    dense_rate = None
    if any(R ** 3 * len(gcs) > dense_max_evals for R in resolutions):
        _, s = timed(lambda: extract_mesh(gcs, fn, rate_resolution, method="dense"))
        dense_rate = s / (rate_resolution ** 3 * len(gcs))
    cases = []
    for R in resolutions:
        K = len(gcs)
        case = {"shape": label, "name": meta["name"], "n_gcs": K, "resolution": R,
                "dense_evals": R ** 3 * K}
        if case["dense_evals"] <= dense_max_evals:
            r, s = timed(lambda: extract_mesh(gcs, fn, R, method="dense"))
            case.update(dense_s=s, dense_s_extrapolated=False)
            dense_rate = s / case["dense_evals"]
        else:
            case.update(dense_s=None if dense_rate is None else dense_rate * case["dense_evals"],
                        dense_s_extrapolated=True)
        pre, s = timed(lambda: extract_mesh(gcs, fn, R, method="prefiltered"))
        case.update(prefiltered_evals=pre.stats["n_network_evals"], prefiltered_s=s)
        extract_mesh(gcs, fn, R)                                           # warm-up
        sp, s = timed(lambda: extract_mesh(gcs, fn, R))
        st = sp.stats
        case.update(sparse_evals=st["n_network_evals"], sparse_s=s,
                    sparse_seconds_network=st["seconds_network"],
                    sparse_seconds_geometry=st["seconds_geometry"],
                    sparse_seconds_marching=st["seconds_marching"],
                    sparse_levels=st["levels"], sparse_repair_rounds=st["repair_rounds"],
                    sparse_active_cells=st["n_active_cells"],
                    faces_sparse=len(sp.mesh.faces), faces_prefiltered=len(pre.mesh.faces),
                    identical_mesh=bool(np.array_equal(sp.mesh.vertices, pre.mesh.vertices)
                                        and np.array_equal(sp.mesh.faces, pre.mesh.faces)),
                    cd_sparse_vs_prefiltered=chamfer(sp.mesh, pre.mesh))
        case["sparse_over_dense_evals"] = case["sparse_evals"] / case["dense_evals"]
        cases.append(case)
        if R > incremental_max:
            print_case(case)
            continue
        # incremental: one GC edited, the others from the cache
        cache = FieldCache()
        extract_mesh(gcs, fn, R, cache=cache, gc_keys=[gc_key(g, c) for g, c in zip(gcs, codes)])
        j = [g.name for g in gcs].index(EDITED_GC[label])
        edited = list(gcs)
        edited[j] = scaled(gcs[j], 1.1)
        keys = [gc_key(g, c) for g, c in zip(edited, codes)]
        inc, s = timed(lambda: extract_mesh(edited, fn, R, cache=cache, gc_keys=keys))
        full, s_full = timed(lambda: extract_mesh(edited, fn, R))
        case.update(incremental_s=s, incremental_evals=inc.stats["n_network_evals"],
                    full_after_edit_s=s_full, full_after_edit_evals=full.stats["n_network_evals"],
                    incremental_identical=bool(
                        np.array_equal(inc.mesh.vertices, full.mesh.vertices)
                        and np.array_equal(inc.mesh.faces, full.mesh.faces)))
        print_case(case)
    return cases


def print_case(case: dict) -> None:
    label, R = case["shape"], case["resolution"]
    edit = (f"edit {case['incremental_s']:.2f} s ({case['incremental_evals']:,d} evals) vs "
            f"{case['full_after_edit_s']:.2f} s" if "incremental_s" in case else "")
    print(f"{label:9s} R={R:3d} evals dense {case['dense_evals']:>11,d} prefiltered "
          f"{case['prefiltered_evals']:>10,d} sparse {case['sparse_evals']:>9,d} "
          f"(1/{1 / case['sparse_over_dense_evals']:.0f} of dense) | s: dense "
          f"{case['dense_s'] if case['dense_s'] is not None else float('nan'):7.1f}"
          f"{'*' if case['dense_s_extrapolated'] else ' '} prefiltered "
          f"{case['prefiltered_s']:6.2f} sparse {case['sparse_s']:6.2f} | CD "
          f"{case['cd_sparse_vs_prefiltered']:.1e} identical {case['identical_mesh']} | "
          f"{edit}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolutions", type=int, nargs="+", default=[128, 256, 512])
    ap.add_argument("--shapes", nargs="+", default=list(SHAPES))
    ap.add_argument("--dense-max-evals", type=float, default=4e7,
                    help="time dense extraction up to this many evaluations, extrapolate above")
    ap.add_argument("--dense-rate-resolution", type=int, default=64,
                    help="resolution at which dense time per evaluation is measured")
    ap.add_argument("--incremental-max-resolution", type=int, default=256)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--steps", type=int, default=1500, help="fit steps (bench/deform.py's fit)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/extract.json")
    args = ap.parse_args()

    import torch

    from deform import fitted
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.extract import SparseSettings
    from ngc_gen.lit.checkpoint import load_autodecoder

    torch.set_num_threads(args.threads)
    load0 = os.getloadavg()[0]
    fit = fitted(args.steps, refit=False)
    module = load_autodecoder(fit["checkpoint"])
    cases = []
    for label in args.shapes:
        cases += run_shape(label, module, args.resolutions, args.dense_max_evals,
                           args.dense_rate_resolution, args.incremental_max_resolution)
    at = {c["shape"]: c for c in cases if c["resolution"] == TARGET_R}
    res = {
        "machine": {"cpus": os.cpu_count(), "threads": args.threads,
                    "python": platform.python_version(), "torch": torch.__version__,
                    "load_avg_1min_at_start": load0, "load_avg_1min_at_end": os.getloadavg()[0]},
        "settings": {"bound": 1.0, "checkpoint": fit["checkpoint"], "fit_steps": fit["steps"],
                     "sparse": dataclasses.asdict(SparseSettings()),
                     "dense_max_evals": args.dense_max_evals,
                     "chamfer": "DeepSDF: 30k samples each way, squared, means summed",
                     "dense_s_extrapolated": "dense_s = measured seconds per evaluation of the "
                                             "same shape x dense_evals"},
        "cases": cases,
        "targets": {"at_resolution": TARGET_R,
                    "sparse_evals_le_dense_over_30": {k: c["sparse_evals"] * 30 <= c["dense_evals"]
                                                      for k, c in at.items()},
                    "cd_lt_1e-6": {k: c["cd_sparse_vs_prefiltered"] < 1e-6 for k, c in at.items()},
                    "creature_sparse_s_le_1": (at["creature"]["sparse_s"] <= 1.0
                                               if "creature" in at else None)},
    }
    print(f"machine load (1 min) at start {load0:.1f}, at end {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores; * = dense time extrapolated")
    print("targets at 256:", json.dumps(res["targets"]))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, json.dumps(res, indent=2))
    print(f"saved {args.out.relative_to(ROOT) if args.out.is_relative_to(ROOT) else args.out}")


if __name__ == "__main__":
    main()
