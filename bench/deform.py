"""Volume and area preservation under handle deformation (paper Tables 2-3): NGC vs libigl ARAP.

    python -m bench.deform [--steps 1500] [--resolution 224] [--refit] [--arap-iters 100]

Inputs: a square bar (generated here, one straight GC along it), a procedural creature and the ant,
fitted together once with NGC (small preset; the fit is kept in the bench's fit cache,
.cache/bench/fits/deform, keyed by its whole recipe: config and the three shapes' data; reused while
that is unchanged, unless --refit). Each case drags the handle vertices of one GC region (mesh
vertices in the GC over a t-range) by a rigid motion and pins the fixed vertices (every vertex
outside that GC, plus the GC's own start region t <= 0.1):
- NGC: `deform_by_handles` with those handle vertices and targets; its fixed region is the
  fixed vertices plus the curve points of the other GCs (the fixed parts' skeletons: a tail
  root sits deep inside the torso, far from the torso's surface vertices); the deformed and
  the undeformed NGC meshes are extracted at the same resolution, and compared.
- ARAP: libigl (`igl.ARAPData`, `igl.arap_precomputation(V, F, 3, b, data)`,
  `igl.arap_solve(bc, data, V)`; spokes-and-rims energy, `--arap-iters` iterations from the rest
  pose) on the input mesh with the same handle and fixed vertices; a connected piece with no
  constraint (the ant has 15 pieces) gets one vertex pinned, so the system is not singular.
eps_V = |V' - V| / V and eps_A = |A' - A| / A (ngc_gen.eval.volume_area_change, fractions; the
tables print percent). time_s: NGC = handle solve + extraction of the deformed mesh; ARAP =
precomputation + solve. Measured in the same run (--matched): edit_to_mesh_s_128 / _256, the
handle solve plus the incremental extraction of the edited shape at 128^3 / 256^3 (the undeformed
shape extracted first, so only the GCs the solve moved are evaluated again), and arap_s_matched,
libigl ARAP with the same handle region and motion on the undeformed NGC 256^3 mesh.

Writes bench/results/deform.json ({cases: [{name, ngc: {eps_v, eps_a, time_s, ...}, arap:
{...}}], mean: {...}, edit_to_mesh_s_128, edit_to_mesh_s_256, arap_s_matched, settings, machine};
bench/_harness.py) and bench/results/deform.png (before / NGC / ARAP for the cases marked
`picture`, the camera on the edited part); its tables are bench/README.md's (bench/report.py).
"""
from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

from bench._handles import BOUND, FIXED_T, Case, run_case
from bench._harness import Bench, cached_run_fit
from bench._tables import pct

ROOT = Path(__file__).resolve().parents[1]
BAR_DIR = ROOT / ".cache/bench/deform/bars"
RESULTS = ROOT / "bench/results"
CREATURE = "creature_0000"

# the bar: 1.6 long along x (already in the normalised frame: longest side 2 x 0.8), square
# cross-section 0.2 x 0.2 with rounded edges; one straight GC from x = -0.7 to 0.7
BAR_HALF = (0.8, 0.1, 0.1)
BAR_ROUND = 0.025


# ---- inputs ----------------------------------------------------------------------------------
def make_bar(out_dir: Path = BAR_DIR, spacing: float = 0.016) -> Path:
    """A watertight rounded square bar (marching cubes of its SDF) and its one-GC annotation;
    written once. Returns the annotation path."""
    import numpy as np
    import trimesh
    import yaml

    from ngc_gen.data.atomic import atomic_write, atomic_write_text
    from ngc_gen.extract import marching_cubes_grid

    ann = out_dir / "bar.yaml"
    if ann.exists():
        return ann
    h = np.array(BAR_HALF)
    axes = [np.arange(-x - 3 * spacing, x + 3 * spacing + 1e-9, spacing) for x in h]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    q = np.abs(P) - (h - BAR_ROUND)
    sdf = np.linalg.norm(np.maximum(q, 0), axis=-1) + np.minimum(q.max(-1), 0) - BAR_ROUND
    mesh = marching_cubes_grid(sdf, [a[0] for a in axes], spacing, float32_spacing=True)
    assert mesh.is_watertight, "bar mesh must be watertight"
    atomic_write(out_dir / "bar.ply", lambda fh: fh.write(mesh.export(file_type="ply")))
    gc = {"name": "bar", "curve": {"type": "bezier", "points": [[-0.7, 0, 0], [0.7, 0, 0]]},
          "up": [0, 0, 1], "keys": [{"t": 0.0, "radii": [0.17, 0.17], "twist": 0.0}],
          "caps": [0.2, 0.2]}
    atomic_write_text(ann, yaml.safe_dump({"name": "bar", "mesh": "bar.ply",
                                           "normalize": {"bound": 0.8}, "gcs": [gc]},
                                          sort_keys=False, default_flow_style=None))
    return ann


def fit_config(steps: int, resolution: int):
    from omegaconf import OmegaConf, open_dict

    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=[
        "stage=fit", "data=demo", "model=small", f"trainer.max_steps={steps}",
        f"extract.resolution={resolution}", "trainer.enable_progress_bar=false", "logger=csv"])
    with open_dict(cfg):
        cfg.data = OmegaConf.create({
            "_target_": "ngc_gen.data.datasets.Combined", "name": "deformbench", "parts": [
                {"_target_": "ngc_gen.data.datasets.AnnotatedShapes", "name": "bars",
                 "annotations": [str(make_bar())]},
                {"_target_": "ngc_gen.data.datasets.Creatures", "name": "creatures",
                 "out_dir": str(ROOT / ".cache/datasets/creatures_n64_s0"), "n": 64, "seed": 0,
                 "split": "train", "test_fraction": 0.25, "limit": 1},
                {"_target_": "ngc_gen.data.datasets.AnnotatedShapes", "name": "ant",
                 "annotations": [str(ROOT / "datasets/ant/ant.yaml")]}]})
    return cfg


def fitted(steps: int, refit: bool) -> dict:
    """The fit, from the bench's fit cache while its recipe (the whole config, the bar's, the
    creature's and the ant's annotations and meshes) is unchanged, else fitted now:
    {checkpoint, train_s, steps, key, fit_cd}."""
    fit = cached_run_fit("deform", fit_config(steps, 128), refit=refit)
    metrics = json.loads((fit.run_dir / "metrics.json").read_text())
    return {"checkpoint": str(fit.run_dir / "checkpoints/last.ckpt"),
            "train_s": fit.info["train_s"], "steps": fit.info["steps"], "key": fit.key,
            "fit_cd": {k: v["cd"] for k, v in metrics["shapes"].items()}}


# ---- cases -----------------------------------------------------------------------------------
CASES = [
    Case("bar_bend_90", "bar", "bar", "bend", 90.0, picture=True),
    Case("bar_bend_180", "bar", "bar", "bend", 180.0, picture=True),
    Case("bar_twist_90", "bar", "bar", "twist", 90.0, picture=True),
    Case("creature_tail_curl", CREATURE, "tail", "bend", 90.0, at=(0.8, 1.0), picture=True),
    Case("creature_leg_raise", CREATURE, "leg_fl", "bend", 40.0, at=(0.85, 1.0),
         up=(1, 0, 0)),
    Case("ant_leg_raise", "ant", "leg_l1", "bend", 45.0, at=(0.85, 1.0), up=(0, 1, 0),
         picture=True),
]


def mean_of(cases: list[dict]) -> dict:
    import numpy as np

    keys = {"ngc": ("eps_v", "eps_a", "time_s", "solve_s"), "arap": ("eps_v", "eps_a", "time_s")}
    return {m: {k: float(np.mean([c[m][k] for c in cases])) for k in ks}
            for m, ks in keys.items()}


def matched_means(cases: list[dict]) -> dict:
    """edit_to_mesh_s_<res> and arap_s_matched, means over the cases that measured them."""
    import numpy as np

    keys = sorted({k for c in cases for k in c["ngc"]
                   if k.startswith("edit_to_mesh_s_") or k == "arap_s_matched"})
    return {k: float(np.mean([c["ngc"][k] for c in cases if k in c["ngc"]])) for k in keys}


def picture(results: list[dict], path: Path, cell=(330, 250)) -> None:
    """Rows of cases, columns NGC before / NGC after / ARAP after; one camera per row, aimed at
    the handle GC before and after, so before and after compare directly. pyvista off screen
    (EGL)."""
    import numpy as np

    import os

    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    y_up = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)  # show the ant z-up
    rows = []
    for r in results:
        if not r.get("_picture"):
            continue
        meshes = [m.copy() for m in r["_meshes"][1:]]
        lo, hi = r["_focus"]  # the handle GC before and after: where the edit happens
        if r["shape"] == "ant":
            for m in meshes:
                m.vertices = m.vertices @ y_up.T
            corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T @ y_up.T
            lo, hi = corners.min(0), corners.max(0)
        rows.append((r["name"], meshes, VIEWS.get(r["shape"], VIEWS["bar"]), lo, hi))
    titles = ["NGC before", "NGC after", "ARAP after (input mesh)"]
    colors = ("#c8a27a", "#7fa7c9", "#9cc28c")
    p = pv.Plotter(off_screen=True, shape=(len(rows), 3), border=False,
                   window_size=(cell[0] * 3, cell[1] * len(rows)))
    p.set_background("white")
    for i, (name, meshes, view, lo, hi) in enumerate(rows):
        c, radius = (lo + hi) / 2, 0.6 * float(np.linalg.norm(hi - lo))
        d = np.asarray(view, float) / np.linalg.norm(view)
        for j, m in enumerate(meshes):
            p.subplot(i, j)
            faces = np.hstack([np.full((len(m.faces), 1), 3), m.faces]).ravel()
            p.add_mesh(pv.PolyData(np.asarray(m.vertices), faces), color=colors[j],
                       smooth_shading=True)
            p.camera_position = [tuple(c + 2.7 * radius * d), tuple(c), (0, 0, 1)]
            p.add_text(f"{titles[j]} / {name}" if j == 0 else titles[j] if i == 0 else "",
                       font_size=8, color="black")
    p.render()
    tmp = path.with_name(f".{path.name}.tmp.png")
    p.screenshot(str(tmp))
    p.close()
    os.replace(tmp, path)


VIEWS = {"bar": (0.35, -1.0, 0.35), CREATURE: (-0.3, -1.0, 0.35), "ant": (0.4, -1.0, 0.45)}


def main():
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--resolution", type=int, default=224)
    ap.add_argument("--arap-iters", type=int, default=100)
    ap.add_argument("--refit", action="store_true")
    ap.add_argument("--matched", type=int, nargs="*", default=[128, 256],
                    help="resolutions for edit_to_mesh_s_<res> (ARAP matched at 256)")
    ap.add_argument("--cases", nargs="+", default=[c.name for c in CASES])
    ap.add_argument("--results", type=Path, default=RESULTS, help="output folder")
    ap.add_argument("--threads", default="auto", help="torch threads: auto (as the entry "
                    "points: the cores the load leaves free), N or null")
    args = ap.parse_args()
    bench = Bench("deform", results=args.results)  # timings need an idle machine: its load
    from ngc_gen.app.runtime.cli import set_threads

    threads = set_threads(None if args.threads == "null" else args.threads)

    import yaml

    from ngc_gen.data.annotations import annotation_from_dict
    from ngc_gen.data.mesh.io import load_mesh, normalize
    from ngc_gen.lit.checkpoint import load_autodecoder

    fit = fitted(args.steps, args.refit)
    module = load_autodecoder(fit["checkpoint"])
    shape_index = {m["name"]: i for i, m in enumerate(module.hparams.meta["shapes"])}
    inputs = {}
    for m in module.hparams.meta["shapes"]:
        ann = annotation_from_dict(yaml.safe_load(m["annotation_yaml"]))
        mesh, _, _ = normalize(load_mesh(ann.mesh_path), ann.bound)
        inputs[m["name"]] = (np.asarray(mesh.vertices), np.asarray(mesh.faces, dtype=np.int64))

    undeformed: dict = {}
    results = []
    for case in CASES:
        if case.name not in args.cases:
            continue
        r = run_case(case, module, shape_index, inputs, args.resolution, args.arap_iters,
                     undeformed, tuple(args.matched))
        r["_picture"] = case.picture
        results.append(r)
        print(f"{case.name:22s} NGC eps_v {100 * r['ngc']['eps_v']:6.2f}% eps_a "
              f"{100 * r['ngc']['eps_a']:6.2f}% ({r['ngc']['time_s']:.1f} s) | ARAP eps_v "
              f"{100 * r['arap']['eps_v']:6.2f}% eps_a {100 * r['arap']['eps_a']:6.2f}% "
              f"({r['arap']['time_s']:.1f} s)", flush=True)
    clean = [{k: v for k, v in r.items() if not k.startswith("_")} for r in results]
    res = {"cases": clean, "mean": mean_of(clean), **matched_means(clean),
           "settings": {"resolution": args.resolution, "bound": BOUND, "steps": args.steps,
                        "arap_iters": args.arap_iters, "fixed_t": FIXED_T,
                        "train_s": fit["train_s"],
                        "checkpoint": str(Path(fit["checkpoint"]).relative_to(ROOT)),
                        "threads": threads}}
    path = bench.write(res)
    picture(results, args.results / "deform.png")
    print()
    print(table(json.loads(path.read_text())))


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(res: dict) -> str:
    lines = ["| case | NGC eps_V | NGC eps_A | NGC time (s) (solve) | ARAP eps_V | ARAP eps_A | "
             "ARAP time (s) |", "|---|---|---|---|---|---|---|"]
    for c in res["cases"] + [{"name": "**mean**", **res["mean"]}]:
        n, a = c["ngc"], c["arap"]
        solve = f" ({n['solve_s']:.2f})" if "solve_s" in n else ""
        lines.append(f"| {c['name']} | {100 * n['eps_v']:.2f}% | {100 * n['eps_a']:.2f}% | "
                     f"{n['time_s']:.2f}{solve} | {100 * a['eps_v']:.2f}% | "
                     f"{100 * a['eps_a']:.2f}% | {a['time_s']:.2f} |")
    s, mv = res["settings"], res["mean"]
    matched = {k: v for k, v in res.items() if k.startswith("edit_to_mesh_s_")}
    if matched:
        lines += ["", "| edit to mesh (handle solve + incremental extraction) | seconds |",
                  "|---|---|"]
        lines += [f"| NGC at {k.rsplit('_', 1)[1]}^3 | {v:.2f} |" for k, v in matched.items()]
        if "arap_s_matched" in res:
            nv = statistics.mean(c["ngc"]["arap_matched_vertices"] for c in res["cases"])
            lines.append(f"| libigl ARAP on the undeformed NGC 256^3 mesh (mean {nv:.0f} "
                         f"vertices), precomputation + solve | {res['arap_s_matched']:.2f} |")
    b = s.get("bound", 1.25)
    lines += ["", f"NGC meshes at {s['resolution']}^3 over [-{b}, {b}]^3, fitted {s['steps']} "
                  f"steps (small preset), {s.get('threads')} torch threads; ARAP "
                  f"{s['arap_iters']} iterations. NGC mean eps_V / ARAP mean eps_V = "
                  f"{mv['ngc']['eps_v'] / mv['arap']['eps_v']:.2f}; eps_A ratio "
                  f"{mv['ngc']['eps_a'] / mv['arap']['eps_a']:.2f} (paper Tables 2-3: NGC "
                  f"0.1-2.6% vs ARAP 5-46% volume change)."]
    return "\n".join(lines)


def headline(r):
    m = r["mean"]
    return (f"volume change NGC {pct(m['ngc']['eps_v'])} vs ARAP {pct(m['arap']['eps_v'])} (mean "
            f"of {len(r['cases'])} edits); edit to mesh at 256^3 {r['edit_to_mesh_s_256']:.2f} s vs "
            f"ARAP {r['arap_s_matched']:.2f} s")


if __name__ == "__main__":
    main()
