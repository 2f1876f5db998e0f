"""Small collections: does the recipe of `experiment=collection` give whole, complete and varied
shapes from 8 training animals where the default recipe does not?

    python -m bench.collection [--species alpaca bull ...] [--shape-latent-steps 3000]
        [--diffusion-steps 3000] [--samples 32] [--resolution 96] [--demo-run DIR]

Training set: one 0 A.D. quadruped per species at rest, 8 species, with the GCs of the
collection template (datasets/animals/quadruped_transfer.yaml) that each animal's own rig gives
(bench/_collection_data.py; `data=folder`, the collection's frame recorded). One
shape-latent run (the collection recipe's, conf/experiment/collection.yaml), then two diffusion
runs on it, each drawing `--samples` shapes (seed 0) meshed at `--resolution`^3:
  small          the collection recipe: principal axes (pca), the dropped ones from the nearest
                 latent, trained also on GC edits of the training shapes (diffusion.augment)
  small_default  the default diffusion (conf/diffusion/default.yaml: per-dimension
                 standardisation, the training latents only), same steps
Per sample: whole (the largest connected piece holds >= 99% of the area), all_gcs (every
template GC holds >= 0.2% of 5000 surface samples, or at least as much as in the training mesh
where it holds least: the ear GCs of a horse hold 0.02%), copy (squared Chamfer, 2048 points each
way, to its nearest training mesh below half the median nearest-neighbour Chamfer among the
training meshes; all in the normalised frame, longest side 1.6). Shares over the samples.
`minutes_demo_collection`: `make demo-collection` on a fresh clone of HEAD, wall clock with its
setup and the 0 A.D. fetch (--fresh-clone; `demo_collection_fresh_clone` has the parts), or a run's
summary.json (--demo-run), else the last recorded value. Writes bench/results/collection.json and collection.png (training animals and
each recipe's first samples).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from bench._collection_data import FRAME, TEMPLATE, training_folder
from bench._harness import Bench, fresh_clone, make_in
from bench._tables import pct, rows_table

ROOT = Path(__file__).resolve().parents[1]

RUNS = ROOT / "bench/runs/collection"


def runs_dir(args) -> Path:
    """The runs of one training set (a run is reused only for the species it was trained on)."""
    return RUNS / "_".join(args.species)
SPECIES = ["bear", "camel", "deer", "elephant", "giraffe", "horse", "pig", "wolf"]
WHOLE, GC_SHARE, N_POINTS = 0.99, 0.002, 2048


def recipe_steps(step: str) -> list[str]:
    """The collection recipe's overrides of one step (conf/experiment/collection.yaml), without
    the links and the data the pipeline fills in."""
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config("train", ["experiment=collection", "data.path=.",
                                   f"annotate.template={TEMPLATE}", "run_dir=."])
    from omegaconf import OmegaConf

    drop = ("data=", "data.name=", "threads=", "prepare.cache_dir=")
    return [o for o in OmegaConf.to_container(cfg.pipeline[step], resolve=True)
            if not o.startswith(drop)]


def data_overrides(args) -> list[str]:
    folder = training_folder(args.species, args.zeroad_deb)
    return ["data=folder", f"data.path={folder}", "threads=1",
            f"prepare.cache_dir={ROOT}/.cache/prepared/collection_bench_zeroad",
            "trainer.enable_progress_bar=false", "logger=csv"]


def train(args) -> dict:
    """The shape-latent run and the two diffusion runs (reused when their directory holds a
    finished run of the same steps)."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.registry import run_stage

    runs = {k: runs_dir(args) / k for k in ("shape_latent", "small", "small_default")}
    sl = [*recipe_steps("shape_latent"), f"shape_latent.max_steps={args.shape_latent_steps}"]
    diffs = {"small": [*recipe_steps("diffusion"), f"diffusion.augment.template={TEMPLATE}"],
             "small_default": []}
    seconds = {}
    plan = [("shape_latent", ["stage=shape_latent", *sl])] + [
        (k, ["stage=diffusion", f"shape_latent_run={runs['shape_latent']}", *v,
             f"diffusion.max_steps={args.diffusion_steps}"]) for k, v in diffs.items()]
    for name, overrides in plan:
        done = runs[name] / "metrics.json"
        if done.is_file() and json.loads(done.read_text()).get("steps") == (
                args.shape_latent_steps if name == "shape_latent" else args.diffusion_steps):
            print(f"{name}: reusing {runs[name]}", flush=True)
            continue
        t0 = time.perf_counter()
        run_stage(compose_config("train", [*data_overrides(args), *overrides,
                                           f"run_dir={runs[name]}"]))
        seconds[name] = time.perf_counter() - t0
    return {"runs": {k: str(v) for k, v in runs.items()}, "train_s": seconds,
            "recipes": {"shape_latent": sl, **diffs}}


def surface_points(mesh, n: int, seed: int = 0):
    """(n, 3) surface samples of a mesh."""
    import numpy as np
    import trimesh

    pts, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts)


def chamfer(a, b) -> float:
    """Squared Chamfer (DeepSDF convention: mean squared distance each way, summed)."""
    from scipy.spatial import cKDTree

    return float((cKDTree(b).query(a)[0] ** 2).mean() + (cKDTree(a).query(b)[0] ** 2).mean())


def training_points(args) -> tuple[dict, dict[str, float]]:
    """The training meshes' surface points in the normalised frame, and per GC the least share
    of a training mesh's surface samples it holds (the training set's own floor)."""
    from hydra.utils import instantiate

    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.data.mesh.io import load_mesh, normalize

    data = instantiate(compose_config("train", [*data_overrides(args), "run_dir=."]).data)
    out, floor = {}, {}
    for ann in data.shapes():
        mesh, _, _ = normalize(load_mesh(ann.mesh_path), ann.bound)
        out[ann.name] = surface_points(mesh, N_POINTS)
        for g, share in gc_shares(mesh, ann.gcs).items():
            floor[g] = min(floor.get(g, 1.0), share)
    return out, floor


def gc_shares(mesh, gcs) -> dict[str, float]:
    """Per GC, the share of 5000 surface samples inside it."""
    import numpy as np

    pts = surface_points(mesh, 5000, seed=1)
    return {g.name: float(np.mean(g.contains(pts))) for g in gcs}


def score_samples(summary: dict, train_pts: dict, copy_below: float, floor: dict) -> dict:
    """whole, all_gcs and copy per sample of a sample.py summary, and their shares."""
    import numpy as np
    import trimesh

    from ngc_gen.data.annotations import load_annotation

    rows = {}
    for name, s in summary["shapes"].items():
        mesh = trimesh.load(s["mesh"], process=False)
        if len(mesh.faces) == 0:
            rows[name] = {"whole": False, "all_gcs": False, "copy": False, "nearest_cd": None}
            continue
        areas = np.array([p.area for p in mesh.split(only_watertight=False)])
        held = gc_shares(mesh, load_annotation(s["annotation"]).gcs)
        p = surface_points(mesh, N_POINTS)
        nearest = min((chamfer(p, t), n) for n, t in train_pts.items())
        rows[name] = {"whole": bool(areas.max() >= WHOLE * areas.sum()),
                      "largest_piece": float(areas.max() / areas.sum()),
                      "all_gcs": all(v >= min(GC_SHARE, floor[g]) for g, v in held.items()),
                      "gcs_missing": sorted(g for g, v in held.items()
                                            if v < min(GC_SHARE, floor[g])),
                      "copy": bool(nearest[0] < copy_below), "nearest_cd": nearest[0],
                      "nearest": nearest[1]}
    n = len(rows)
    return {"n_samples": n, **{k: sum(r[k] for r in rows.values()) / n
                               for k in ("whole", "all_gcs")},
            "copies": sum(r["copy"] for r in rows.values()) / n, "per_sample": rows}


def render(args, path: Path, per_row: int = 6) -> None:
    """collection.png: training animals, then the samples of each recipe, upright in the
    collection's frame."""
    import trimesh
    from hydra.utils import instantiate

    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.data.mesh.io import load_mesh, normalize
    from ngc_gen.viz import render_grid, render_or_warn

    data = instantiate(compose_config("train", [*data_overrides(args), "run_dir=."]).data)
    train = [normalize(load_mesh(a.mesh_path), a.bound)[0] for a in data.shapes()][:per_row]
    rows, labels = [train], ["training animals"]
    for recipe in ("small", "small_default"):
        files = sorted((runs_dir(args) / f"samples_{recipe}").glob("sample_*.ply"))[:per_row]
        rows.append([trimesh.load(f, process=False) for f in files])
        labels.append(f"generated: {recipe}")
    render_or_warn(render_grid, path, rows, labels=labels, frame="row", up=FRAME["up"])


def table(r: dict) -> str:
    """bench/README.md's table: both recipes on the same training animals."""
    rows = [[f"`{k}`", r[k]["n_train"], r[k]["n_samples"], pct(r[k]["whole"], 0),
             pct(r[k]["all_gcs"], 0), pct(r[k]["copies"], 0)] for k in ("small", "small_default")]
    minutes = r.get("minutes_demo_collection")
    rows.append(["`make demo-collection`", "", "", "", "",
                 "not run" if minutes is None else f"{minutes:.1f} min"
                 + (" (fresh clone)" if r.get("demo_collection_fresh_clone") else "")])
    return "\n".join(rows_table(["recipe", "training", "samples", "whole", "all GCs", "copies"],
                                 rows))


def headline(r: dict) -> str:
    s, d = r["small"], r["small_default"]
    return (f"8 training animals, 32 samples: whole {pct(s['whole'], 0)} (default recipe "
            f"{pct(d['whole'], 0)}), copies {pct(s['copies'], 0)}, all GCs "
            f"{pct(s['all_gcs'], 0)} ({pct(d['all_gcs'], 0)})")


def record_fresh_clone(args, bench: Bench) -> None:
    """`make demo-collection` on a fresh clone, wall clock from `make` to the overview picture:
    a new .venv, the 0ad-data fetch and cache, annotate ... interpolate. Keeps the rest."""
    import os


    commit, work, clone = fresh_clone("HEAD", None, "ngc_demo_collection_")
    env = dict(os.environ)
    if args.zeroad_deb:
        env["ZEROAD_DEB"] = str(Path(args.zeroad_deb).resolve())
    print(f"make demo-collection in {clone} (commit {commit[:7]}, load {bench.load_before}) ...",
          flush=True)
    wall = make_in(clone, "demo-collection", work / "make_demo_collection.log", env=env)
    summary = json.loads((clone / "outputs/demo_collection/run/summary.json").read_text())
    old = json.loads(bench.path.read_text()) if bench.path.is_file() else {}
    old.pop("machine", None)
    fresh = {"commit": commit, "make_wall_s": round(wall, 1),
             "pipeline_s": round(summary["total_s"], 1),
             "setup_and_fetch_s": round(wall - summary["total_s"], 1),
             "zeroad_deb_given": bool(args.zeroad_deb)}
    print(f"make demo-collection on a fresh clone: {wall / 60:.1f} min "
          f"({fresh['setup_and_fetch_s']:.0f} s setup and fetch)")
    result = {**old, "minutes_demo_collection": wall / 60, "demo_collection_fresh_clone": fresh}
    print(f"wrote {bench.write(result)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--species", nargs="+", default=SPECIES)
    ap.add_argument("--shape-latent-steps", type=int, default=3000)
    ap.add_argument("--diffusion-steps", type=int, default=3000)
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--zeroad-deb", default=None,
                    help="the 0ad-data .deb (else ZEROAD_DEB or apt-get download, once)")
    ap.add_argument("--demo-run", type=Path, default=None,
                    help="a `make demo-collection` run directory (its summary.json's minutes)")
    ap.add_argument("--fresh-clone", action="store_true",
                    help="time `make demo-collection` on a fresh clone of HEAD (setup, the 0 A.D. "
                         "fetch and the run) and record its minutes in the existing results")
    ap.add_argument("--demo-only", action="store_true",
                    help="only record --demo-run's minutes in the existing results")
    ap.add_argument("--picture-only", action="store_true",
                    help="only draw bench/results/collection.png from the bench's runs")
    args = ap.parse_args()
    bench = Bench("collection")
    if args.picture_only:
        render(args, bench.results / "collection.png")
        return
    if args.fresh_clone:
        record_fresh_clone(args, bench)
        return
    if args.demo_only:
        old = json.loads(bench.path.read_text()) if bench.path.is_file() else {}
        old.pop("machine", None)
        minutes = json.loads((args.demo_run / "summary.json").read_text())["total_s"] / 60
        print(f"make demo-collection: {minutes:.1f} min")
        print(f"wrote {bench.write({**old, 'minutes_demo_collection': minutes})}")
        return
    from ngc_gen.app.runtime.cli import set_threads
    from ngc_gen.app.stages.sample import generate
    from ngc_gen.generate import load_generator

    import numpy as np

    set_threads(1)
    trained = train(args)
    train_pts, floor = training_points(args)
    names = list(train_pts)
    nn = [min(chamfer(train_pts[a], train_pts[b]) for b in names if b != a) for a in names]
    copy_below = 0.5 * float(np.median(nn))
    res = {}
    for recipe in ("small", "small_default"):
        out = runs_dir(args) / f"samples_{recipe}"
        summary = generate(load_generator(trained["runs"][recipe]), out, n=args.samples, seed=0,
                           resolution=args.resolution, progress=False)
        scored = score_samples(summary, train_pts, copy_below, floor)
        res[recipe] = {"n_train": len(names), **scored,
                       "recipe": trained["recipes"][recipe] or "conf/diffusion/default.yaml"}
        print(f"{recipe:14s} whole {scored['whole']:.2f}  all GCs {scored['all_gcs']:.2f}  "
              f"copies {scored['copies']:.2f}  ({len(names)} training animals, "
              f"{scored['n_samples']} samples)", flush=True)
    minutes = None
    if args.demo_run is not None:
        minutes = json.loads((args.demo_run / "summary.json").read_text())["total_s"] / 60
    elif bench.path.is_file():
        minutes = json.loads(bench.path.read_text()).get("minutes_demo_collection")
    result = {**res, "minutes_demo_collection": minutes,
              "protocol": {"species": args.species, "data": "0 A.D. rest poses, rig GCs of the collection template",
                           "shape_latent_steps": args.shape_latent_steps,
                           "diffusion_steps": args.diffusion_steps,
                           "resolution": args.resolution, "points": N_POINTS,
                           "copy_below": copy_below, "train_nn_chamfer_median": float(np.median(nn)),
                           "whole": f"largest piece >= {WHOLE} of the area",
                           "all_gcs": f"every GC holds >= {GC_SHARE} of the surface samples, or "
                                      "as much as the training mesh holding least of it",
                           "gc_floor": floor},
              "train_s": trained["train_s"]}
    print(f"wrote {bench.write(result)}")
    render(args, bench.results / "collection.png")


if __name__ == "__main__":
    main()
