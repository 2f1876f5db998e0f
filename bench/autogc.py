"""Automatic GCs (docs/autogc.md): what a user gets on meshes no one annotated.

    python -m bench.autogc [--creatures 16] [--fit-creatures 4] [--steps 1500] [--resolution 128]

1. Annotate with the default settings (conf/annotate/default.yaml): pyvista's ant (15 pieces)
   and airplane (open), and `--creatures` procedural creatures (true template: 10 parts). Per
   mesh: GC count, coverage and overlap (share of 50k surface samples inside >= 1 and >= 2
   GCs), seconds (after one untimed warm-up annotation: the process's one-time start is
   `settings.warmup_s`). Creatures: |count - 10| and, per true part, the share of its surface samples
   (each sample labelled by the true GC it is relatively nearest to) inside one automatic GC.
   The ant: the same share for each of its six legs; the airplane: whether fuselage, wings and
   tail parts get different automatic GCs.
2. NGC fits at equal steps (small preset, the fit stage) on the ant, the airplane and the first
   `--fit-creatures` creatures with automatic GCs, hand annotations and the one-GC axis method,
   each from every training seed of `--seeds` (cd_* and nc_* are the means over the seeds, the
   values per seed in cd_*_per_seed: the six shapes share one network, so a seed, or a change
   of any one shape's GCs, moves a creature's auto/axis ratio by up to 0.1):
   Chamfer (DeepSDF convention), the same Chamfer against the ground truth's surface
   (`cd_surface_*`, exact distances: the sample-to-sample estimator's noise floor is as large as
   a good fit's Chamfer) and normal consistency per shape; cd_noise_floor, the DeepSDF-convention
   Chamfer between two samplings of the ground truth (what a perfect fit reads: no ratio to
   cd_axis can go below cd_noise_floor / cd_axis).
3. A handle edit (a leg raised, bench/deform.py's bend) on the automatically annotated creature
   and ant: eps_V, eps_A of the deformed against the undeformed NGC mesh.
Writes bench/results/autogc.json ({meshes: [{name, n_gcs, coverage, overlap, time_s, cd_auto,
cd_annotated, cd_axis, nc_auto, ...}], creatures: {count_err_mean, count_err_max,
part_single_gc_mean, part_single_gc_worst}, ant, airplane, edits, settings, machine};
bench/_harness.py) and bench/results/autogc.png (automatic GCs over the ant, the airplane and two
creatures). The fits are kept in the bench's fit cache (.cache/bench/fits/autogc), keyed by
their whole recipe (config, annotations, meshes): rerunning with the same settings reuses them.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench._harness import Bench, cached_run_fit, load_1min
from bench._tables import pct, rows_table

if TYPE_CHECKING:
    import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "bench/runs/autogc"
RESULTS = ROOT / "bench/results"
CREATURES = ROOT / ".cache/datasets/creatures_n64_s0"
HAND = {"ant": ROOT / "datasets/ant/ant.yaml", "airplane": ROOT / "datasets/airplane/airplane.yaml"}
MESHES = {"ant": "pyvista:ant.ply", "airplane": "pyvista:airplane.ply"}
COVERAGE_SAMPLES = 50_000
METHODS = ("auto", "annotated", "axis")


def single_gc_shares(true_gcs, auto_gcs, points) -> np.ndarray:
    """(T,) per true GC: the largest share of its surface samples inside one automatic GC. A
    sample belongs to the true GC it is relatively nearest to (smallest rho)."""
    import numpy as np

    from ngc_gen.data.autogc.coverage import rho_matrix
    from ngc_gen.data.mesh.sampling import gc_membership

    part = rho_matrix(true_gcs, points)[0].argmin(axis=0)
    pp, pg, _ = gc_membership(points, auto_gcs)
    inside = np.zeros((len(points), len(auto_gcs)), dtype=bool)
    inside[pp, pg] = True
    return np.array([inside[part == k].mean(axis=0).max() if (part == k).any() else 1.0
                     for k in range(len(true_gcs))])


def warm_up(mesh: str) -> float:
    """One untimed annotation first: the process's one-time start (numba loading its compiled
    kernels, CGAL's module) is not a mesh's time. -> its seconds, reported apart."""
    from ngc_gen.data.autogc.auto import auto_annotation

    t0 = time.perf_counter()
    auto_annotation(mesh, name="warm_up", bound=0.8)
    seconds = time.perf_counter() - t0
    print(f"warm-up (first annotation in this process): {seconds:.2f} s", flush=True)
    return seconds


def annotate_all(names: dict, hand: dict) -> tuple[list[dict], dict]:
    """Automatic annotations of every mesh (written to RUNS/annotations) and their figures."""
    import numpy as np

    from ngc_gen.data.annotations import load_annotation, save_annotation
    from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
    from ngc_gen.data.autogc.coverage import coverage_stats
    from ngc_gen.data.mesh.io import load_mesh, normalize
    from ngc_gen.data.mesh.sampling import sample_surface
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=["run_dir=/tmp"])
    settings = AutoGCSettings.from_config(cfg.annotate)
    rows, anns = [], {}
    for name, mesh in names.items():
        t0 = time.perf_counter()
        ann = auto_annotation(mesh, name=name, bound=0.8, settings=settings)
        seconds = time.perf_counter() - t0
        save_annotation(ann, RUNS / "annotations" / f"{name}.yaml")
        normalized, _, _ = normalize(load_mesh(mesh), 0.8)
        points, _ = sample_surface(normalized.vertices, normalized.faces, COVERAGE_SAMPLES,
                                   np.random.default_rng(1))
        st = coverage_stats(ann.gcs, points)
        row = {"name": name, "n_gcs": len(ann.gcs), "coverage": st["coverage"],
               "overlap": st["overlap"], "time_s": seconds, "gc_names": ann.gc_names}
        if name in hand:
            true = load_annotation(hand[name]).gcs
            shares = single_gc_shares(true, ann.gcs, points)
            row["part_single_gc"] = {g.name: float(s) for g, s in zip(true, shares)}
            # which automatic GC holds most of each true part
            best = []
            for g in true:
                share_per_auto = single_gc_best(true, ann.gcs, points, g.name)
                best.append(share_per_auto)
            row["best_auto_gc"] = {g.name: b for g, b in zip(true, best)}
        rows.append(row)
        anns[name] = ann
        print(f"{name:16s} {len(ann.gcs):3d} GCs  coverage {100 * st['coverage']:7.3f}%  overlap "
              f"{st['overlap']:.3f}  {seconds:6.2f} s  load {load_1min()}", flush=True)
    return rows, anns


def single_gc_best(true_gcs, auto_gcs, points, part_name: str) -> str:
    """Name of the automatic GC holding the largest share of a true part's samples."""
    import numpy as np

    from ngc_gen.data.autogc.coverage import rho_matrix
    from ngc_gen.data.mesh.sampling import gc_membership

    k = [g.name for g in true_gcs].index(part_name)
    part = rho_matrix(true_gcs, points)[0].argmin(axis=0) == k
    pp, pg, _ = gc_membership(points[part], auto_gcs)
    counts = np.bincount(pg, minlength=len(auto_gcs))
    return auto_gcs[int(np.argmax(counts))].name


FIT_DIRS: dict = {}   # (method, seed) -> the fit's folder in the fit cache, set by fit()


def run_dir_of(method: str, seed: int = 0) -> Path:
    return FIT_DIRS[method, seed]


def fit(method: str, names: list[str], hand: dict, steps: int, resolution: int,
        seed: int = 0) -> dict:
    """One NGC fit of the shapes with `method` GCs (auto | annotated | axis) from training seed
    `seed`; per-shape metrics."""
    from omegaconf import OmegaConf, open_dict

    from ngc_gen.app.runtime.config import compose_config

    files = [str(RUNS / "annotations" / f"{n}.yaml") if method == "auto" else str(hand[n])
             for n in names]
    data = {"_target_": "ngc_gen.data.datasets.AnnotatedShapes", "name": f"autogc_{method}",
            "annotations": files}
    if method == "axis":
        data = {"_target_": "ngc_gen.data.datasets.SingleGC", "name": "autogc_axis",
                "base": {**data, "name": "autogc_hand"}}
    cfg = compose_config(overrides=[
        "stage=fit", "model=small", f"trainer.max_steps={steps}", f"extract.resolution={resolution}",
        "trainer.enable_progress_bar=false", "logger=csv", f"seed={seed}"])
    with open_dict(cfg):
        cfg.data = OmegaConf.create(data)
    label = f"fit_{method}" if seed == 0 else f"fit_{method}_seed{seed}"
    # the fit cache: reused while the config and the annotations' and meshes' bytes match
    f = cached_run_fit("autogc", cfg, label=label)
    FIT_DIRS[method, seed] = f.run_dir
    metrics = json.loads((f.run_dir / "metrics.json").read_text())
    metrics["wall_s"] = f.info["wall_s"]
    return metrics


def ground_truth(name: str, method: str = "axis", seed: int = 0):
    """The ground-truth mesh a fit run scored `name` against (its prepared cache)."""
    import trimesh
    from omegaconf import OmegaConf

    from ngc_gen.data.prepare import load_prepared

    cache = Path(OmegaConf.load(run_dir_of(method, seed) / "config.yaml").prepare.cache_dir)
    gt = load_prepared(cache / f"{name}.npz")
    return trimesh.Trimesh(gt.mesh_vertices, gt.mesh_faces, process=False)


def surface_chamfer(method: str, name: str, seed: int = 0) -> float:
    """Chamfer of a fit's mesh against the surface of its ground truth (`mesh_chamfer`: exact
    point-to-mesh distances), free of the sample-to-sample estimator's noise floor (~1e-4 on a
    creature, bench/extract.py), which the DeepSDF-convention cd of a good fit sits on."""
    import trimesh

    from ngc_gen.eval.fitting import mesh_chamfer

    pred = trimesh.load(run_dir_of(method, seed) / "meshes" / f"{name}.ply", process=False)
    return mesh_chamfer(pred, ground_truth(name, method, seed))


def cd_noise_floor(name: str, seed: int = 0, n: int = 30000) -> float:
    """The DeepSDF-convention Chamfer between two samplings (seeds 0 and 1, n points each) of the
    same ground-truth surface: what the fit's cd reads for a perfect fit. A ratio cd_x / cd_axis
    cannot go below cd_noise_floor / cd_axis, whatever GCs x are."""
    from ngc_gen.eval.fitting import chamfer
    from ngc_gen.eval.point_samples import sample_surface

    mesh = ground_truth(name, seed=seed)
    return chamfer(sample_surface(mesh, n, 0)[0], sample_surface(mesh, n, 1)[0])


def edits(checkpoint: str, anns: dict, resolution: int) -> list[dict]:
    """A leg raised on the automatically annotated creature and ant (bench/deform.py's bend)."""
    import numpy as np
    import yaml

    from bench._handles import Case, run_case
    from ngc_gen.data.annotations import annotation_from_dict, load_annotation
    from ngc_gen.data.mesh.io import load_mesh, normalize
    from ngc_gen.lit.checkpoint import load_autodecoder

    module = load_autodecoder(checkpoint)
    metas = module.hparams.meta["shapes"]
    index = {m["name"]: i for i, m in enumerate(metas)}
    inputs = {}
    for m in metas:
        ann = annotation_from_dict(yaml.safe_load(m["annotation_yaml"]))
        mesh, _, _ = normalize(load_mesh(ann.mesh_path), ann.bound)
        inputs[m["name"]] = (np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64))
    creature = next(n for n in index if n.startswith("creature"))
    # the automatic GC that holds most of the true front-left leg
    leg = single_gc_best(load_annotation(CREATURES / f"{creature}.yaml").gcs, anns[creature].gcs,
                         inputs[creature][0], "leg_fl")
    ant_leg = single_gc_best(load_annotation(HAND["ant"]).gcs, anns["ant"].gcs,
                             inputs["ant"][0], "leg_l1")
    cases = [Case(f"{creature}_{leg}_raise", creature, leg, "bend", 40.0, at=(0.85, 1.0), up=(1, 0, 0)),
             Case(f"ant_{ant_leg}_raise", "ant", ant_leg, "bend", 45.0, at=(0.85, 1.0), up=(0, 1, 0))]
    out, undeformed = [], {}
    for case in cases:
        r = run_case(case, module, index, inputs, resolution, 100, undeformed)
        out.append({"name": case.name, "shape": case.shape, "gc": case.gc,
                    "eps_v": r["ngc"]["eps_v"], "eps_a": r["ngc"]["eps_a"],
                    "handle_err": r["ngc"]["handle_err"], "arap_eps_v": r["arap"]["eps_v"]})
        print(f"edit {case.name}: eps_V {100 * r['ngc']['eps_v']:.2f}% eps_A "
              f"{100 * r['ngc']['eps_a']:.2f}% (ARAP eps_V {100 * r['arap']['eps_v']:.2f}%)", flush=True)
    return out


def picture(anns: dict, names: list[str], path: Path) -> None:
    import trimesh

    from ngc_gen.data.mesh.io import load_mesh, normalize
    from ngc_gen.viz import gcs_surface, render_grid

    rows, labels = [], []
    for n in names:
        ann = anns[n]
        mesh, _, _ = normalize(load_mesh(ann.mesh_path), ann.bound)
        shell = gcs_surface(ann.gcs)
        rows.append([(mesh, shell), trimesh.Trimesh(shell.vertices, shell.faces)])
        labels.append(f"{n}: {len(ann.gcs)} GCs")
    render_grid(rows, path, labels=labels, col_titles=["automatic GCs over the mesh", "the GCs"],
                cell=(360, 270))


def part_stats(by_name: dict, creatures: list[str]) -> tuple[dict, dict, dict]:
    """How the automatic GCs split the true parts: over the creatures (GC count, share of a
    part in one GC), the ant's legs, the airplane's fuselage, wings and tail."""
    import numpy as np

    cr = [by_name[c] for c in creatures]
    err = np.array([abs(r["n_gcs"] - 10) for r in cr])
    shares = np.array([s for r in cr for s in r["part_single_gc"].values()])
    worst_per_shape = [min(r["part_single_gc"].values()) for r in cr]
    creature_stats = {"n_shapes": len(cr), "count_err_mean": float(err.mean()),
                      "count_err_max": int(err.max()), "part_single_gc_mean": float(shares.mean()),
                      "part_single_gc_worst": float(shares.min()),
                      "part_single_gc_worst_per_shape_mean": float(np.mean(worst_per_shape)),
                      "parts_below_0.8": int((shares < 0.8).sum()), "parts_total": int(len(shares)),
                      "per_part_mean": {p: float(np.mean([r["part_single_gc"][p] for r in cr]))
                                        for p in cr[0]["part_single_gc"]}}
    ant = by_name["ant"]
    legs = {k: v for k, v in ant["part_single_gc"].items() if k.startswith("leg")}
    leg_gcs = [ant["best_auto_gc"][k] for k in legs]
    ant_stats = {"legs_single_gc": legs, "legs_own_gc": len(set(leg_gcs)) == len(leg_gcs),
                 "leg_gcs": dict(zip(legs, leg_gcs))}
    air = by_name["airplane"]
    groups = {"fuselage": ["fuselage"], "wings": ["wing_l", "wing_r"],
              "tail": ["stabilizer_l", "stabilizer_r", "fin_l", "fin_r"]}
    air_best = {g: sorted({air["best_auto_gc"][p] for p in ps}) for g, ps in groups.items()}
    flat = [x for v in air_best.values() for x in v]
    air_stats = {"best_auto_gc": air_best, "separate": len(flat) == len(set(flat)),
                 "part_single_gc": air["part_single_gc"]}
    return creature_stats, ant_stats, air_stats


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--creatures", type=int, default=16)
    ap.add_argument("--fit-creatures", type=int, default=4)
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--edit-resolution", type=int, default=192)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1],
                    help="training seeds of the fits; cd_* are their means (one seed moved a "
                         "creature's auto/axis ratio by up to 0.1)")
    ap.add_argument("--skip-fits", action="store_true")
    return ap.parse_args()


def main():
    import numpy as np

    args = parse_args()
    bench = Bench("autogc")
    t_start = time.perf_counter()

    import torch

    from ngc_gen.data.procedural.creatures import build_creatures

    torch.set_num_threads(1)  # a shared 2-core machine: one thread is faster
    build_creatures(CREATURES, 64, seed=0)
    creatures = [f"creature_{i:04d}" for i in range(args.creatures)]
    hand = {**HAND, **{c: CREATURES / f"{c}.yaml" for c in creatures}}
    meshes = {**MESHES, **{c: str(CREATURES / f"{c}.ply") for c in creatures}}
    warmup_s = warm_up(meshes[creatures[0]])
    rows, anns = annotate_all(meshes, hand)
    by_name = {r["name"]: r for r in rows}

    creature_stats, ant_stats, air_stats = part_stats(by_name, creatures)

    fit_names = ["ant", "airplane"] + creatures[: args.fit_creatures]
    fits = {}                               # (method, seed) -> the fit's metrics
    if not args.skip_fits:
        for seed in args.seeds:
            for method in METHODS:
                fits[method, seed] = f = fit(method, fit_names, hand, args.steps, args.resolution,
                                             seed)
                print(f"fit {method} seed {seed}: " + ", ".join(
                    f"{n} cd {m['cd']:.2e}" for n, m in f["shapes"].items()), flush=True)
    for r in rows:
        fitted_here = bool(fits) and r["name"] in fit_names
        for method in METHODS:
            per = [fits[method, s]["shapes"][r["name"]] for s in args.seeds] if fitted_here else []
            cd = [float(m["cd"]) for m in per]
            surface = [surface_chamfer(method, r["name"], s) for s in args.seeds] \
                if fitted_here else []
            r[f"cd_{method}"] = float(np.mean(cd)) if per else None
            r[f"cd_surface_{method}"] = float(np.mean(surface)) if per else None
            r[f"cd_{method}_per_seed"] = cd or None
            r[f"cd_surface_{method}_per_seed"] = surface or None
            if method != "axis":
                r[f"nc_{method}"] = float(np.mean([m["normal_consistency"] for m in per])) \
                    if per else None
        r["cd_noise_floor"] = cd_noise_floor(r["name"], args.seeds[0]) if fitted_here else None
    edit_rows = edits(fits["auto", args.seeds[0]]["checkpoint"], anns, args.edit_resolution) \
        if fits else []

    fitted = [r for r in rows if r["cd_auto"] is not None]
    targets = {"time_s_max": max(r["time_s"] for r in rows),
               "coverage_min": min(r["coverage"] for r in rows), **ratio_targets(fitted)}
    res = {"meshes": rows, "creatures": creature_stats, "ant": ant_stats, "airplane": air_stats,
           "edits": edit_rows, "targets": targets,
           "settings": {"steps": args.steps, "resolution": args.resolution, "seeds": args.seeds,
                        "fit_shapes": fit_names, "edit_resolution": args.edit_resolution,
                        "warmup_s": warmup_s,
                        "total_s": time.perf_counter() - t_start,
                        "conventions": "coverage/overlap: share of 50k surface samples inside >= 1 / "
                                       ">= 2 GCs; cd: DeepSDF Chamfer (30k points each way, squared, "
                                       "means summed); cd_noise_floor: that Chamfer between two "
                                       "samplings of the ground truth (a perfect fit's cd); "
                                       "cd_surface_*: the same against the other "
                                       "mesh's surface (exact distances, mesh_chamfer); nc: normal "
                                       "consistency; eps_V = |V'-V|/V"}}
    bench.write(res)
    picture(anns, ["ant", "airplane", creatures[0], creatures[1]], RESULTS / "autogc.png")
    print_summary(res)


RATIOS = [("cd", "auto", "annotated"), ("cd", "auto", "axis"), ("cd", "annotated", "axis"),
          ("cd", "noise_floor", "axis"), ("cd_surface", "auto", "annotated"),
          ("cd_surface", "auto", "axis"), ("cd_surface", "annotated", "axis")]
RATIOS_PER_SEED = [("cd_surface", "auto", "axis"), ("cd", "auto", "axis")]


def ratio_targets(fitted: list[dict]) -> dict:
    """{"<p>_<a>_over_<b>": {mesh: <p>_<a> / <p>_<b>}} for RATIOS (the means over the seeds),
    and the same per seed ("..._per_seed": {mesh: [one ratio per seed]}) for RATIOS_PER_SEED."""
    out = {}
    for p, a, b in RATIOS:
        out[f"{p}_{a}_over_{b}"] = {r["name"]: r[f"{p}_{a}"] / r[f"{p}_{b}"] for r in fitted}
    for p, a, b in RATIOS_PER_SEED:
        out[f"{p}_{a}_over_{b}_per_seed"] = {
            r["name"]: [x / y for x, y in zip(r[f"{p}_{a}_per_seed"], r[f"{p}_{b}_per_seed"])]
            for r in fitted}
    return out


def print_summary(res: dict) -> None:
    print(f"\n{'mesh':16s} {'GCs':>4s} {'coverage':>9s} {'overlap':>8s} {'s':>6s} {'cd_auto':>9s} "
          f"{'cd_annot':>9s} {'cd_axis':>9s} {'nc_auto':>8s}")
    f = lambda x, w, p: f"{x:{w}.{p}}" if x is not None else f"{'-':>{w}s}"  # noqa: E731
    for r in res["meshes"]:
        print(f"{r['name']:16s} {r['n_gcs']:4d} {100 * r['coverage']:8.3f}% {r['overlap']:8.3f} "
              f"{r['time_s']:6.2f} {f(r['cd_auto'], 9, '2e')} {f(r['cd_annotated'], 9, '2e')} "
              f"{f(r['cd_axis'], 9, '2e')} {f(r['nc_auto'], 8, '3f')}")
    t = res["targets"]
    for key, per_mesh in t.items():              # the ratio targets (ratio_targets)
        if key.endswith("_per_seed"):
            print(f"{key:36s} " + "  ".join(f"{n} " + "/".join(f"{v:.2f}" for v in vs)
                                             for n, vs in per_mesh.items()))
        elif isinstance(per_mesh, dict):
            print(f"{key:32s} " + "  ".join(f"{n} {v:.2f}" for n, v in per_mesh.items()))
    c = res["creatures"]
    print(f"creatures ({c['n_shapes']}): |GCs - 10| mean {c['count_err_mean']:.2f} max "
          f"{c['count_err_max']}; true part inside one automatic GC: mean "
          f"{c['part_single_gc_mean']:.3f}, worst {c['part_single_gc_worst']:.3f} "
          f"({c['parts_below_0.8']} of {c['parts_total']} parts below 0.8)")
    print(f"ant: every leg its own GC: {res['ant']['legs_own_gc']} {res['ant']['leg_gcs']}")
    print(f"airplane: fuselage / wings / tail separate: {res['airplane']['separate']} "
          f"{res['airplane']['best_auto_gc']}")
    print(f"total {res['settings']['total_s']:.0f} s")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
AUTOGC_COLUMNS = [("cd_auto", "CD auto"), ("cd_annotated", "CD hand"), ("cd_axis", "CD axis")]


def table(r: dict) -> str:
    t = r["targets"]
    ratio = lambda key, name: (f"{t[key][name]:.2f}" if name in t.get(key, {}) else "-")  # noqa: E731
    rows = []
    for m in r["meshes"]:
        fitted = m.get("cd_auto") is not None
        per = t.get("cd_surface_auto_over_axis_per_seed", {}).get(m["name"])
        rows.append([m["name"], m["n_gcs"], pct(m["coverage"], 3), f"{m['overlap']:.2f}",
                     f"{m['time_s']:.1f}"]
                    + [f"{m[k]:.2e}" if fitted else "-" for k, _ in AUTOGC_COLUMNS]
                    + [ratio("cd_auto_over_annotated", m["name"]),
                       ratio("cd_auto_over_axis", m["name"]),
                       ratio("cd_annotated_over_axis", m["name"]),
                       ratio("cd_noise_floor_over_axis", m["name"]),
                       ratio("cd_surface_auto_over_annotated", m["name"]),
                       ratio("cd_surface_auto_over_axis", m["name"])
                       + (" (" + "/".join(f"{x:.2f}" for x in per) + ")" if per else ""),
                       ratio("cd_surface_annotated_over_axis", m["name"]),
                       f"{m['nc_auto']:.3f}" if m.get("nc_auto") is not None else "-"])
    s = r["settings"]
    seeds = "/".join(map(str, s["seeds"]))
    lines = rows_table(["mesh", "GCs", "coverage", "overlap", "seconds"]
                       + [c for _, c in AUTOGC_COLUMNS]
                       + ["auto / hand", "auto / axis", "hand / axis", "floor / axis",
                          "surface CD: auto / hand", f"auto / axis (seed {seeds})",
                          "hand / axis", "NC auto"], rows)
    c, ant, air = r["creatures"], r["ant"], r["airplane"]
    lines += ["", f"Creatures ({c['n_shapes']}, true template: 10 parts): GC count off by "
                  f"{c['count_err_mean']:.2f} on average, at most {c['count_err_max']}; a true part "
                  f"has on average {pct(c['part_single_gc_mean'], 1)} of its surface samples "
                  f"inside one automatic GC, the worst part {pct(c['part_single_gc_worst'], 1)} "
                  f"({c['parts_below_0.8']} of {c['parts_total']} parts below 80%). The ant: every "
                  f"leg its own GC: {'yes' if ant['legs_own_gc'] else 'no'}; the airplane: "
                  f"fuselage, wings and tail in different GCs: "
                  f"{'yes' if air['separate'] else 'no'}. Fits: {s['steps']} steps, seeds "
                  f"{', '.join(map(str, s['seeds']))} (CDs are their means), meshes at "
                  f"{s['resolution']}^3; annotation warm-up {s['warmup_s']:.1f} s; "
                  f"{s['total_s']:.0f} s in all."]
    if r.get("edits"):
        lines += ["", "Leg raised by handles on automatic GCs: " + "; ".join(
            f"{e['name']}: eps_V {pct(e['eps_v'])}, eps_A {pct(e['eps_a'])} (ARAP eps_V "
            f"{pct(e['arap_eps_v'])})" for e in r["edits"]) + "."]
    return "\n".join(lines)


def headline(r):
    t, c = r["targets"], r["creatures"]
    return (f"{len(r['meshes'])} meshes, coverage >= {pct(t['coverage_min'], 2)}, at most "
            f"{t['time_s_max']:.1f} s each; {pct(c['part_single_gc_mean'], 1)} of a creature part "
            f"in one GC")


if __name__ == "__main__":
    main()
