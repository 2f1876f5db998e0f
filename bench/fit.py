"""Fitting benchmark (paper Table 1 form): NGC (multi-GC), NGC (one GC) and DeepSDF trained on
the same shapes with the same number of steps, batch size and samples per shape.

    python bench/fit.py [--steps 1500] [--resolution 128]

Writes bench/results/fit.json ({methods: {ngc, ngc_1gc, deepsdf: {cd, hd, emd, train_s}},
shapes, ...}) and bench/results/fit.md (the README table). Also checks on the fitted NGC that
the extractor's GC prefilter is exact (identical grids with and without it) and records both
evaluation counts. Runs go to bench/runs/fit/<method>.
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

METHODS = {  # name -> (data config, model config, extra overrides)
    "ngc": ("fitbench", "small", []),
    "ngc_1gc": ("fitbench_1gc", "small", []),
    # DeepSDF's own sampling: the same near-surface samples, volume samples in the whole box
    # (a world-space SDF has to learn the empty space outside the GCs as well)
    "deepsdf": ("fitbench", "deepsdf_small", [
        "prepare.volume_region=box", "prepare.cache_dir=${paths.cache_dir}/prepared/fitbench_box"]),
}


def run(method: str, steps: int, resolution: int, batch_size: int) -> dict:
    from ngc_gen.app.config import compose_config
    from ngc_gen.app.fit import run_fit

    data, model, extra = METHODS[method]
    run_dir = ROOT / "bench/runs/fit" / method
    cfg = compose_config(overrides=[
        "stage=fit", f"data={data}", f"model={model}", f"trainer.max_steps={steps}",
        f"extract.resolution={resolution}", f"batch_size={batch_size}", f"run_dir={run_dir}",
        "trainer.enable_progress_bar=false", "logger=csv", *extra])
    return run_fit(cfg)


def prefilter_check(checkpoint: str, resolution: int) -> dict:
    import torch

    from ngc_gen.shape import autodecoder_mesh
    from ngc_gen.lit.checkpoint import load_autodecoder

    module = load_autodecoder(checkpoint)
    out = {"shape": module.hparams.meta["shapes"][0]["name"], "resolution": resolution}
    for key in ("prefiltered", "dense"):
        t0 = time.perf_counter()
        with torch.no_grad():   # fixed batches: a row's value cannot depend on its batch
            r = autodecoder_mesh(module, 0, resolution, keep_values=True, method=key,
                                 fixed_batch=True)
        out[key] = {"n_network_evals": int(r.stats["n_network_evals"]),
                    "seconds": time.perf_counter() - t0}
        out.setdefault("_values", []).append(r.values)
        out.setdefault("_meshes", []).append(r.mesh)
    a, b = out.pop("_values")
    ma, mb = out.pop("_meshes")
    out["identical_grid"] = bool(np.array_equal(a, b))
    out["identical_mesh"] = bool(np.array_equal(ma.vertices, mb.vertices)
                                 and np.array_equal(ma.faces, mb.faces))
    out["eval_ratio"] = out["dense"]["n_network_evals"] / out["prefiltered"]["n_network_evals"]
    return out


def picture(res: dict, path: Path, max_shapes: int = 4) -> None:
    """bench/results/fit.png: per shape, ground truth beside each method's mesh."""
    import trimesh

    from ngc_gen.data.prepare import load_prepared
    from ngc_gen.viz import render_grid

    methods = [m for m in METHODS if m in res["methods"]]
    rows = []
    for shape in res["shapes"][:max_shapes]:
        prep = load_prepared(ROOT / ".cache/prepared/fitbench" / f"{shape}.npz")
        row = [trimesh.Trimesh(prep.mesh_vertices, prep.mesh_faces, process=False)]
        row += [trimesh.load(ROOT / "bench/runs/fit" / m / "meshes" / f"{shape}.ply", process=False)
                for m in methods]
        rows.append(row)
    render_grid(rows, path, labels=res["shapes"][:max_shapes],
                col_titles=["ground truth"] + [LABELS[m] for m in methods], cell=(300, 240))


LABELS = {"ngc": "NGC, multi-GC", "ngc_1gc": "NGC, one GC", "deepsdf": "DeepSDF"}


def markdown(res: dict) -> str:
    lines = ["| method | CD (x1e-4) | HD | EMD | train time (s) |", "|---|---|---|---|---|"]
    for name, label in LABELS.items():
        if name not in res["methods"]:
            continue
        m = res["methods"][name]
        lines.append(f"| {label} | {m['cd'] * 1e4:.2f} | {m['hd']:.4f} | {m['emd']:.4f} | "
                     f"{m['train_s']:.0f} |")
    r = (res["methods"]["ngc"]["cd"] / res["methods"]["deepsdf"]["cd"]
         if {"ngc", "deepsdf"} <= set(res["methods"]) else float("nan"))
    lines.append("")
    lines.append(f"Mean over {len(res['shapes'])} shapes ({', '.join(res['shapes'])}); "
                 f"{res['steps']} steps of {res['batch_size']} samples each, small presets "
                 f"(~47k parameters each), meshes at {res['resolution']}^3. NGC CD / DeepSDF CD "
                 f"= {r:.2f} (paper: 0.53). CD: 30k points each way, squared distances, means "
                 f"summed (DeepSDF); HD: symmetric Hausdorff; EMD: exact assignment on 2048 "
                 f"points, mean distance.")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--batch-size", type=int, default=8192)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--check-resolution", type=int, default=64)
    ap.add_argument("--methods", nargs="+", default=list(METHODS))
    args = ap.parse_args()
    old = ROOT / "bench/results/fit.json"
    res = {"methods": {}, "per_shape": {}}
    if set(args.methods) != set(METHODS) and old.exists():  # rerun some methods, keep the rest
        res = json.loads(old.read_text())
    res.update(steps=args.steps, batch_size=args.batch_size, resolution=args.resolution)
    for method in args.methods:
        metrics = run(method, args.steps, args.resolution, args.batch_size)
        res["methods"][method] = {k: metrics["mean"][k] for k in ("cd", "hd", "emd")}
        res["methods"][method]["train_s"] = metrics["train_s"]
        res["per_shape"][method] = metrics["shapes"]
        res["shapes"] = list(metrics["shapes"])
        if method == "ngc":
            res["prefilter"] = prefilter_check(metrics["checkpoint"], args.check_resolution)
    out = ROOT / "bench/results"
    out.mkdir(parents=True, exist_ok=True)
    for name, text in (("fit.json", json.dumps(res, indent=2)), ("fit.md", markdown(res))):
        tmp = out / (name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, out / name)
    picture(res, out / "fit.png")
    print(markdown(res))
    if "prefilter" in res:
        p = res["prefilter"]
        print(f"prefilter on {p['shape']} at {p['resolution']}^3: identical grid "
              f"{p['identical_grid']}, mesh {p['identical_mesh']}; network evals "
              f"{p['prefiltered']['n_network_evals']} vs dense {p['dense']['n_network_evals']} "
              f"({p['eval_ratio']:.1f}x fewer)")


if __name__ == "__main__":
    main()
