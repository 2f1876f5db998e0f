"""Fitting benchmark (paper Table 1 form): NGC (multi-GC), NGC (one GC) and DeepSDF trained on
the same shapes with the same number of steps, batch size and samples per shape.

    python -m bench.fit [--steps 1500] [--resolution 128]
    python -m bench.fit --tag pe4 --set model.decoder.pe_frequencies=4 --methods ngc --limit 3
    python -m bench.fit --deepsdf-long 20000      # DeepSDF's recipe, long (resumable)

Writes bench/results/fit.json ({methods: {ngc, ngc_1gc, deepsdf: {cd, hd, emd, nc, fscore,
fragments, gt_fragments, train_s, load}}, shapes, junctions, ..., machine}; nc = mean normal
consistency, fscore = mean F-score@0.01, fragments = components under 1% of the faces summed
over the shapes, load = the 1-, 5- and 15-minute load averages before and after that method's
training; machine: bench/_harness.py); its table is bench/README.md's (bench/report.py).
Also checks on the fitted NGC that the extractor's GC prefilter is exact (identical grids with
and without it) and records both evaluation counts. Runs go to bench/runs/fit/<method> and
start fresh: the training is what this bench measures, so it is never taken from a cache.

`--junctions`: the seams benchmark (bench/_seams.py): the ant, the airplane, 8 creatures
and 6 animals, each fitted on its own with automatic and with its own GCs, before and after the
seam remedies and DeepSDF at about equal time. fit.json `junctions`: one entry per mesh, GCs
and recipe, {name, gcs, recipe, method, junction_ratio_dist, junction_ratio_normal,
extra_pieces, nc, fscore, train_s, steps} (ngc_gen.eval.junctions; docs/metrics.md): the fit's
error where GCs meet / elsewhere, loose pieces, and the mesh's NC and F@0.01; gcs: auto /
annotated / rig; recipe: before / after / deepsdf. Fits are cached; `--only NAME_GCS ...`
fits a part, rerunning fills in the rest (entries of other meshes are kept).
fit_junctions.png: the worst junctions close up. The other modes keep `junctions` as it is
(their joint fits' junction figures are in `per_shape`).

Screening (ablations): `--tag NAME` writes runs and results to bench/runs/fit/NAME/ instead,
`--set` adds overrides to the NGC methods, `--limit N` keeps N of the 6 creatures.

`--rescore`: score the existing runs (and the ceiling) again under the current metrics, keeping
their training times: after a change to `ngc_gen.eval`, nothing is trained again.

`--deepsdf-long STEPS`: the fair baseline, model=deepsdf (DeepSDF's own recipe: 8 x 512, latent
skip at 4, clamp 0.1, lr 5e-4 / 1e-3 halved every quarter of the steps) on DeepSDF's sampling,
same batch. It resumes bench/runs/fit/deepsdf_long (kill it any time; rerun to continue;
`--score-only` scores what is there), keeps checkpoints at the NGC run's training time, and
writes `deepsdf_long` = {cd, nc, fscore, steps, train_s, at_ngc_time: {...}} into fit.json.
"""
from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

from bench._harness import Bench, load_avg
from bench._tables import rows_table, sci
from ngc_gen.data.atomic import atomic_write_text

ROOT = Path(__file__).resolve().parents[1]

LABELS = {"ngc": "NGC, multi-GC", "ngc_1gc": "NGC, one GC", "deepsdf": "DeepSDF"}
METHODS = {  # name -> (data config, model config, extra overrides)
    "ngc": ("fitbench", "small", []),
    "ngc_1gc": ("fitbench_1gc", "small", []),
    # DeepSDF's own sampling: the same near-surface samples, volume samples in the whole box
    # (a world-space SDF has to learn the empty space outside the GCs as well)
    "deepsdf": ("fitbench", "deepsdf_small", [
        "prepare.volume_region=box", "prepare.cache_dir=${paths.cache_dir}/prepared/fitbench_box"]),
}


def fit_config(method: str, steps: int, resolution: int, batch_size: int, run_dir: Path,
               extra: list[str] = ()):
    from ngc_gen.app.runtime.config import compose_config

    data, model, own = METHODS[method]
    return compose_config(overrides=[
        "stage=fit", f"data={data}", f"model={model}", f"trainer.max_steps={steps}",
        f"extract.resolution={resolution}", f"batch_size={batch_size}", f"run_dir={run_dir}",
        "trainer.enable_progress_bar=false", "logger=csv", *own, *extra])


def run(method: str, steps: int, resolution: int, batch_size: int, run_root: Path,
        extra: list[str] = ()) -> dict:
    """A fresh fit run of one method in run_root/<method> (an earlier one is removed)."""
    from ngc_gen.app.stages.fit import run_fit

    run_dir = run_root / method
    if run_dir.exists():
        shutil.rmtree(run_dir)
    return run_fit(fit_config(method, steps, resolution, batch_size, run_dir, list(extra)))


def score_checkpoint(cfg, checkpoint: Path, out_dir: Path, **mesh_kwargs) -> dict:
    """Mesh and score every shape of a fit checkpoint (the fit stage's own scoring, the
    junction measure at the shapes' prepared GCs included)."""
    import torch

    from ngc_gen.app.stages.fit import junction_settings, named_gcs, reconstruct
    from ngc_gen.app.stages.prepare_data import prepare_dataset
    from ngc_gen.lit.checkpoint import load_autodecoder

    prepared = prepare_dataset(cfg)
    module = load_autodecoder(checkpoint).eval()
    gt = {s.name: (s.mesh_vertices, s.mesh_faces) for s in prepared}
    with torch.no_grad():
        return reconstruct(module, out_dir, gt, resolution=cfg.extract.resolution,
                           bound=cfg.extract.bound, chunk=cfg.extract.chunk,
                           seed=cfg.metrics_seed, gcs=named_gcs(prepared),
                           junctions=junction_settings(cfg), **mesh_kwargs)


JOINT_STEPS = 1500   # the joint fits' steps unless --steps

LONG_MARKS = (42, 100, 200, 300, 400, 600, 900, 1200, 1800, 3600, 7200, 14400)
COARSE = {"coarse_step": 4, "lipschitz": 1.0}  # DeepSDF 8 x 512 meshes: coarse-to-fine


def clock_of(checkpoint: Path) -> tuple[float, int]:
    """(training seconds summed over resumed segments, global step) of a checkpoint."""
    import torch

    state = torch.load(checkpoint, map_location="cpu", weights_only=True)
    clock = next(v for k, v in state["callbacks"].items() if "TrainClock" in k)
    return float(clock["seconds"]), int(state["global_step"])


def deepsdf_long(steps: int, resolution: int, batch_size: int, ngc_seconds: float,
                 run_root: Path, score_only: bool = False) -> dict:
    """DeepSDF's own recipe (model=deepsdf) trained for `steps` in run_root/deepsdf_long,
    resumed if it is there; its numbers at the end (or where it was stopped) and at the last
    wall-time mark not past `ngc_seconds` (the NGC run's training time)."""
    import numpy as np

    import lightning as L
    import torch

    from ngc_gen.app.stages.fit import build_module, shapes_meta
    from ngc_gen.app.stages.prepare_data import prepare_dataset
    from ngc_gen.app.runtime.training import start_run, train
    from ngc_gen.data.datamodule import PreparedDataModule
    from ngc_gen.lit.checkpoint import load_autodecoder

    run_dir = run_root / "deepsdf_long"
    marks = ",".join(str(m) for m in LONG_MARKS)
    cfg = fit_config("deepsdf", steps, resolution, batch_size, run_dir, [
        "model=deepsdf", "code_balance=0.0", "callbacks.checkpoint.every_n_train_steps=100",
        "+callbacks.clock._target_=ngc_gen.app.runtime.training.TrainClock",
        f"+callbacks.clock.dirpath={run_dir}", f"+callbacks.clock.marks=[{marks}]"])
    if not score_only:
        prepared = prepare_dataset(cfg)
        start_run(cfg)
        L.seed_everything(cfg.seed, workers=True, verbose=False)
        dm = PreparedDataModule(prepared, mode="deepsdf", batch_size=cfg.batch_size,
                                seed=cfg.seed)
        train(cfg, run_dir, build_module(cfg, dm.n_codes, shapes_meta(prepared, "deepsdf")),
              datamodule=dm)
    last = run_dir / "checkpoints/last.ckpt"
    seconds, step = clock_of(last)
    metrics = score_checkpoint(cfg, last, run_dir / "meshes", **COARSE)
    out = method_summary({**metrics, "train_s": seconds, "steps": step})
    out.update(max_steps=steps, batch_size=batch_size, resolution=resolution,
               clock_csv=str((run_dir / "clock.csv").relative_to(ROOT)),
               loss_last_fifth=loss_last_fifth(run_dir / "clock.csv", step))
    # coarse-to-fine meshes equal dense ones where the field is 2-Lipschitz: check one shape
    module = load_autodecoder(last).eval()
    from ngc_gen.shape import autodecoder_mesh
    with torch.no_grad():
        a = autodecoder_mesh(module, 0, 64, cfg.extract.bound, cfg.extract.chunk)
        b = autodecoder_mesh(module, 0, 64, cfg.extract.bound, cfg.extract.chunk, **COARSE)
    out["coarse_check"] = {"resolution": 64, "shape": module.hparams.meta["shapes"][0]["name"],
                           "identical_mesh": bool(np.array_equal(a.mesh.vertices,
                                                                 b.mesh.vertices)
                                                  and np.array_equal(a.mesh.faces,
                                                                     b.mesh.faces)),
                           "evals": [a.stats["n_network_evals"], b.stats["n_network_evals"]]}
    fit = [m for m in LONG_MARKS if m <= ngc_seconds and (run_dir / f"at_{m:g}s.ckpt").exists()]
    if fit:
        early = run_dir / f"at_{fit[-1]:g}s.ckpt"
        seconds, step = clock_of(early)
        m = score_checkpoint(cfg, early, run_dir / f"meshes_at_{fit[-1]:g}s", **COARSE)
        out["at_ngc_time"] = method_summary({**m, "train_s": seconds, "steps": step})
        out["at_ngc_time"]["junctions"] = junction_rows(m["shapes"], "deepsdf",
                                                        "deepsdf_long_at_ngc_time")
    return out


def ceiling(resolution: int) -> dict:
    """What the metrics allow at this grid: every shape's exact signed distance (the training
    labels' own) meshed by the same marching cubes and scored like a fit. No fit can beat it
    by much: thin parts under a grid cell break up, and creases are rounded."""
    import numpy as np
    import trimesh

    from bench._seams import exact_sdf_mesh
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.fit import junction_settings
    from ngc_gen.app.stages.prepare_data import prepare_dataset
    from ngc_gen.eval import junction_metrics, reconstruction_metrics

    cfg = compose_config(overrides=["stage=fit", "data=fitbench", "run_dir=/tmp/ngc-ceiling"])
    per = {}
    for s in prepare_dataset(cfg, verbose=False):
        mesh = exact_sdf_mesh(s.mesh_vertices, s.mesh_faces, resolution)
        truth = trimesh.Trimesh(s.mesh_vertices, s.mesh_faces, process=False)
        m = reconstruction_metrics(mesh, truth, seed=cfg.metrics_seed)
        m.update(junction_metrics(mesh, truth, s.gcs(), seed=cfg.metrics_seed,
                                  **junction_settings(cfg)))
        per[s.name] = {k: m[k] for k in ("cd", "hd", "normal_consistency", "fscore",
                                         "fragments", "junction_ratio_dist",
                                         "junction_ratio_normal", "extra_pieces")}
    mean = {k: float(np.mean([p[k] for p in per.values()])) for k in ("cd", "hd")}
    mean.update(nc=float(np.mean([p["normal_consistency"] for p in per.values()])),
                fscore=float(np.mean([p["fscore"] for p in per.values()])),
                fragments=int(sum(p["fragments"] for p in per.values())))
    return {"resolution": resolution, "mean": mean, "per_shape": per}


def prefilter_check(checkpoint: str, resolution: int) -> dict:
    import numpy as np
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


def picture(res: dict, path: Path, run_root: Path, max_shapes: int = 4) -> None:
    """bench/results/fit.png: per shape, ground truth beside each method's mesh."""
    import trimesh

    from ngc_gen.data.prepare import load_prepared
    from ngc_gen.viz import render_grid

    methods = [m for m in METHODS if m in res["methods"]]
    rows = []
    for shape in res["shapes"][:max_shapes]:
        prep = load_prepared(ROOT / ".cache/prepared/fitbench" / f"{shape}.npz")
        row = [trimesh.Trimesh(prep.mesh_vertices, prep.mesh_faces, process=False)]
        row += [trimesh.load(run_root / m / "meshes" / f"{shape}.ply", process=False)
                if (run_root / m / "meshes" / f"{shape}.ply").exists() else None
                for m in methods]
        rows.append(row)
    render_grid(rows, path, labels=res["shapes"][:max_shapes],
                col_titles=["ground truth"] + [LABELS[m] for m in methods], cell=(300, 240))


def loss_last_fifth(clock_csv: Path, steps: int) -> list[float] | None:
    """[first, last]: the mean training loss of the first and of the last quarter of the
    clock rows over the last fifth of `steps` (bench/runs/fit/.../clock.csv), so the result
    says whether the loss still fell at the end; None with too few rows."""
    import numpy as np

    if not clock_csv.is_file():
        return None
    rows = np.loadtxt(clock_csv, delimiter=",", ndmin=2)
    rows = rows[rows[:, 0] <= steps]
    late = rows[rows[:, 0] >= 0.8 * steps]
    if len(late) < 4:
        return None
    k = max(1, len(late) // 4)
    return [float(late[:k, 2].mean()), float(late[-k:, 2].mean())]


def rescore(run_dir: Path, resolution: int) -> dict:
    """Score a finished fit run again (its own config and last checkpoint, meshes at
    `resolution`) and rewrite its metrics.json: for metric changes, without training again."""
    from omegaconf import OmegaConf

    from ngc_gen.app.runtime.config import compose_config

    metrics_path = run_dir / "metrics.json"
    metrics = json.loads(metrics_path.read_text())
    cfg = OmegaConf.load(run_dir / "config.yaml")
    base = compose_config(overrides=["stage=fit"])
    for group in ("prepare", "extract", "metrics"):   # keys added since the run: today's defaults
        cfg[group] = OmegaConf.merge(base[group], cfg.get(group) or {})
    cfg.extract.resolution = int(resolution)
    checkpoint = run_dir / "checkpoints/last.ckpt"
    coarse = COARSE if cfg.model.decoder.get("_target_", "").endswith("DeepSDFDecoder") else {}
    metrics.update(score_checkpoint(cfg, checkpoint, run_dir / "meshes", **coarse),
                   checkpoint=str(checkpoint))
    atomic_write_text(metrics_path, json.dumps(metrics, indent=2))
    return metrics


GCS = "annotated"   # the fitbench's GCs: the ant's hand annotation, the creatures' own parts


def junction_rows(per_shape: dict, recipe: str, method: str, gcs: str = GCS) -> list[dict]:
    """A run's per-shape metrics -> its entries of fit.json's `junctions` (shapes scored
    before the junction measure existed are left out)."""
    return [{"name": name, "gcs": gcs, "recipe": recipe, "method": method,
             "junction_ratio_dist": m["junction_ratio_dist"],
             "junction_ratio_normal": m["junction_ratio_normal"],
             "extra_pieces": m["extra_pieces"], "nc": m["normal_consistency"],
             "fscore": m["fscore"]}
            for name, m in per_shape.items() if "junction_ratio_dist" in m]


def method_summary(metrics: dict) -> dict:
    """A fit run's metrics.json -> the bench's numbers of one method."""
    mean, per = metrics["mean"], metrics["shapes"].values()
    out = {k: mean[k] for k in ("cd", "hd", "emd")}
    out.update(nc=mean["normal_consistency"], fscore=mean["fscore"],
               nc_samples=mean.get("nc_samples"), fscore_samples=mean.get("fscore_samples"),
               fragments=int(sum(p["fragments"] for p in per)),
               gt_fragments=int(sum(p["gt_fragments"] for p in per)),
               train_s=metrics["train_s"], steps=metrics["steps"])
    return out


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=None,
                    help=f"training steps (joint fits: {JOINT_STEPS}; --junctions: the fit recipe's)")
    ap.add_argument("--batch-size", type=int, default=8192)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--check-resolution", type=int, default=64)
    ap.add_argument("--methods", nargs="+", default=list(METHODS))
    ap.add_argument("--tag", default=None, help="screening: runs and results in bench/runs/fit/TAG")
    ap.add_argument("--set", nargs="*", default=[], help="extra overrides for the NGC methods")
    ap.add_argument("--limit", type=int, default=None, help="screening: only N creatures")
    ap.add_argument("--threads", type=int, default=None,
                    help="torch CPU threads (default: all cores; 1 is faster on a busy machine)")
    ap.add_argument("--deepsdf-long", type=int, default=None, metavar="STEPS")
    ap.add_argument("--score-only", action="store_true", help="--deepsdf-long: score, no training")
    ap.add_argument("--rescore", action="store_true",
                    help="score the existing runs again under the current metrics (no training)")
    ap.add_argument("--junctions", action="store_true",
                    help="the seams benchmark: meshes fitted one by one (bench/_seams.py)")
    ap.add_argument("--recipes", nargs="+", default=["before", "after", "deepsdf"],
                    help="--junctions: which recipes")
    ap.add_argument("--only", nargs="*", default=None,
                    help="--junctions: only these meshes (ant, or ant_auto / cow_rig)")
    ap.add_argument("--fit-workers", type=int, default=2, help="--junctions: fits side by side")
    ap.add_argument("--refit", action="store_true", help="--junctions: fit again, not cached")
    return ap.parse_args()


def main():
    args = parse_args()
    if args.junctions:
        return junctions_main(args)
    args.steps = args.steps or JOINT_STEPS
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    out = ROOT / "bench/results" if args.tag is None else ROOT / "bench/runs/fit" / args.tag
    run_root = ROOT / "bench/runs/fit" if args.tag is None else out
    bench = Bench("fit", results=out)
    old = bench.path

    def earlier() -> dict:  # the result on disk, less its machine record (written anew)
        r = json.loads(old.read_text())
        r.pop("machine", None)
        return r

    res = {"methods": {}, "per_shape": {}}
    if (set(args.methods) != set(METHODS) or args.deepsdf_long or args.rescore) and old.exists():
        res = earlier()  # rerun some methods, keep the rest
    if args.deepsdf_long:
        load0 = load_avg()
        ngc_s = res["methods"].get("ngc", {}).get("train_s", 42.0)
        long = deepsdf_long(args.deepsdf_long, args.resolution, args.batch_size, ngc_s, run_root,
                            args.score_only)
        long["load"] = load0 + load_avg()
        if old.exists():  # the other methods may have been rerun meanwhile (a long run)
            res = earlier()
        res["deepsdf_long"] = long
        args.methods = []
    else:
        res.update(resolution=args.resolution)
        if not args.rescore:
            res.update(steps=args.steps, batch_size=args.batch_size, threads=args.threads)
    for method in args.methods:
        extra = list(args.set) if method.startswith("ngc") else []
        if args.limit:  # fitbench_1gc wraps fitbench as `base`
            extra.append(f"data.{'base.' * (method == 'ngc_1gc')}parts.1.limit={args.limit}")
        load0 = load_avg()
        if args.rescore:  # the training's own record stays: load and overrides
            metrics = rescore(run_root / method, args.resolution)
            kept = {k: res["methods"].get(method, {}).get(k) for k in ("load", "overrides")}
            res["methods"][method] = {**method_summary(metrics), **kept}
        else:
            metrics = run(method, args.steps, args.resolution, args.batch_size, run_root, extra)
            res["methods"][method] = method_summary(metrics)
            res["methods"][method]["load"] = load0 + load_avg()
            res["methods"][method]["overrides"] = extra
        res["per_shape"][method] = metrics["shapes"]
        res["shapes"] = list(metrics["shapes"])
        if method == "ngc" and args.tag is None:
            res["prefilter"] = prefilter_check(metrics["checkpoint"], args.check_resolution)
    if args.tag is None and not args.deepsdf_long and (
            args.rescore or res.get("ceiling", {}).get("resolution") != args.resolution):
        res["ceiling"] = ceiling(args.resolution)
    if old.exists() and args.tag is None:   # the seams benchmark's entries (--junctions)
        res["junctions"] = earlier().get("junctions", [])
    bench.write(res)
    picture(res, out / "fit.png", run_root)
    print(table(earlier()))
    if "prefilter" in res:
        p = res["prefilter"]
        print(f"prefilter on {p['shape']} at {p['resolution']}^3: identical grid "
              f"{p['identical_grid']}, mesh {p['identical_mesh']}; network evals "
              f"{p['prefiltered']['n_network_evals']} vs dense {p['dense']['n_network_evals']} "
              f"({p['eval_ratio']:.1f}x fewer)")


def junctions_main(args) -> None:
    """--junctions: fit what is missing, merge the entries into fit.json, draw the close-ups."""
    from bench import _seams as junctions

    bench = Bench("fit")
    for r in args.recipes:
        if r not in junctions.RECIPES:
            raise SystemExit(f"--recipes: {r!r} is not one of {list(junctions.RECIPES)}")
    rows, runs = junctions.run(args.recipes, args.only, args.fit_workers, args.steps, args.refit)
    res = json.loads(bench.path.read_text()) if bench.path.exists() else {}
    res.pop("machine", None)
    res["junctions"] = junctions.merge_rows(res.get("junctions", []), rows)
    bench.write(res)
    junctions.picture(res["junctions"], {**junctions.labelled_runs(), **runs},
                      bench.path.parent / "fit_junctions.png")
    print("\n".join(fit_junctions(res["junctions"])))


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def _gt_fragments(res: dict):
    counts = {m.get("gt_fragments") for m in res["methods"].values()} - {None}
    return counts.pop() if len(counts) == 1 else "-"


def _long_status(long: dict) -> str:
    done = "it ran its whole schedule" if long["steps"] >= long["max_steps"] else \
        f"it has not finished its schedule ({long['steps']} of {long['max_steps']} steps)"
    fall = long.get("loss_last_fifth")
    if not fall:
        return done
    a, b = fall
    return (f"{done}; its training loss fell {100 * (a - b) / a:.0f}% over the last fifth of "
            f"the steps ({a:.2e} -> {b:.2e})")


def table(res: dict) -> str:
    lines = ["| method | CD (x1e-4) | HD | EMD | NC | F@0.01 | fragments | train time (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, label in LABELS.items():
        if name not in res["methods"]:
            continue
        m = res["methods"][name]
        lines.append(f"| {label} | {m['cd'] * 1e4:.2f} | {m['hd']:.4f} | {m['emd']:.4f} | "
                     f"{m.get('nc', float('nan')):.3f} | {m.get('fscore', float('nan')):.3f} | "
                     f"{m.get('fragments', '-')} | {m['train_s']:.0f} |")
    long = res.get("deepsdf_long")
    if long:
        for label, m in (("DeepSDF, own recipe, at NGC's time", long.get("at_ngc_time")),
                         (f"DeepSDF, own recipe, {long['steps']} steps", long)):
            if m:
                lines.append(f"| {label} | {m['cd'] * 1e4:.2f} | {m['hd']:.4f} | "
                             f"{m['emd']:.4f} | {m['nc']:.3f} | {m['fscore']:.3f} | "
                             f"{m['fragments']} | {m['train_s']:.0f} |")
    r = (res["methods"]["ngc"]["cd"] / res["methods"]["deepsdf"]["cd"]
         if {"ngc", "deepsdf"} <= set(res["methods"]) else float("nan"))
    lines.append("")
    lines.append(f"Mean over {len(res['shapes'])} shapes ({', '.join(res['shapes'])}); "
                 f"{res['steps']} steps of {res['batch_size']} samples each, small presets "
                 f"(~47k parameters each), meshes at {res['resolution']}^3. NGC CD / DeepSDF CD "
                 f"= {r:.2f} (paper: 0.53). Fragments of the ground truth: "
                 f"{_gt_fragments(res)}.")
    if "ceiling" in res:
        c = res["ceiling"]["mean"]
        lines.append("")
        lines.append(f"Ceiling at {res['ceiling']['resolution']}^3 (each shape's exact signed "
                     f"distance meshed and scored the same way): CD {c['cd'] * 1e4:.2f}e-4, NC "
                     f"{c['nc']:.3f}, F@0.01 {c['fscore']:.3f}, fragments {c['fragments']}.")
    if long and "ngc" in res["methods"]:
        lines.append("")
        lines.append(f"DeepSDF, own recipe: lr halved every quarter of {long['max_steps']} "
                     f"steps; stopped at step {long['steps']}, meshes at "
                     f"{long.get('resolution', res['resolution'])}^3 (coarse-to-fine). NGC CD / "
                     f"its CD = {res['methods']['ngc']['cd'] / long['cd']:.2f} (paper: 0.53); "
                     f"{_long_status(long)}.")
    p = res.get("prefilter")
    if p:
        lines.append("")
        lines.append(f"GC prefilter on the fitted {p['shape']} at {p['resolution']}^3: grids "
                     f"identical {p['identical_grid']}, meshes identical {p['identical_mesh']}; "
                     f"{p['eval_ratio']:.0f}x fewer network evaluations than dense.")
    if res.get("junctions"):
        lines += ["", *fit_junctions(res["junctions"],
                                     res.get("ceiling", {}).get("per_shape", {}))]
    return "\n".join(lines)


JUNCTION_TARGET = 1.3   # junction error / elsewhere error, distance and normal


def fit_junctions(rows: list[dict], ceiling: dict | None = None) -> list[str]:
    """fit.json's `junctions`: per shape and run, the fit's error where GCs meet / elsewhere
    (distance, normal angle), extra pieces, NC and F@0.01, beside the ceiling's junction
    ratios (the shape's exact SDF on the same grid, where measured); then how many meet the
    targets."""
    def r(x):
        return "-" if x is None or x != x else f"{x:.2f}"

    own = {(j["name"], j["gcs"]): j["ceiling"] for j in rows if j.get("ceiling")}

    def ceil(j):   # the mesh's own ceiling (bench/_seams.py), else the fitbench's by name
        c = own.get((j["name"], j["gcs"])) or (ceiling or {}).get(j["name"], {})
        if "junction_ratio_dist" not in c:
            return "-"
        return f"{r(c['junction_ratio_dist'])} / {r(c['junction_ratio_normal'])}"

    out = rows_table(["shape", "GCs", "recipe", "junction / elsewhere: distance", "normal",
                      "extra pieces", "NC", "F@0.01", "ceiling: distance / normal"],
                     [[j["name"], j["gcs"], j["recipe"], r(j["junction_ratio_dist"]),
                       r(j["junction_ratio_normal"]), j["extra_pieces"], f"{j['nc']:.3f}",
                       f"{j['fscore']:.3f}", ceil(j)] for j in rows])
    for recipe in dict.fromkeys(j["recipe"] for j in rows):
        mine = [j for j in rows if j["recipe"] == recipe]
        ratios = [max(j["junction_ratio_dist"], j["junction_ratio_normal"]) for j in mine
                  if j["junction_ratio_dist"] is not None]   # None: no junction
        met = sum(x <= JUNCTION_TARGET for x in ratios)
        capped = [j for j in mine if own.get((j["name"], j["gcs"]))
                  and j["junction_ratio_dist"] is not None
                  and own[(j["name"], j["gcs"])]["junction_ratio_dist"] is not None]
        within = sum(j["junction_ratio_dist"] <= own[(j["name"], j["gcs"])]["junction_ratio_dist"]
                     and j["junction_ratio_normal"]
                     <= own[(j["name"], j["gcs"])]["junction_ratio_normal"] for j in capped)
        out.append("")
        out.append(f"{recipe}: junction / elsewhere <= {JUNCTION_TARGET} (distance and normal) "
                   f"on {met} of {len(ratios)} meshes"
                   + (f", worst {max(ratios):.2f}" if ratios else "")
                   + (f"; at or below its mesh's ceiling on {within} of {len(capped)}"
                      if capped else "")
                   + f"; {sum(j['extra_pieces'] for j in mine)} extra pieces; NC >= 0.95 on "
                   f"{sum(j['nc'] >= 0.95 for j in mine)}, F >= 0.95 on "
                   f"{sum(j['fscore'] >= 0.95 for j in mine)} of {len(mine)}.")
    return out


def headline(r):
    n, d = r["methods"]["ngc"], r["methods"]["deepsdf"]
    return (f"{len(r['shapes'])} shapes, {r['steps']} steps: NGC CD {sci(n['cd'], -4)}, NC "
            f"{n['nc']:.3f}, F {n['fscore']:.3f}; DeepSDF, same budget: {sci(d['cd'], -4)}, "
            f"{d['nc']:.3f}, {d['fscore']:.3f}")


if __name__ == "__main__":
    main()
