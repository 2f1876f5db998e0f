"""Volume and area preservation under handle deformation (paper Tables 2-3): NGC vs libigl ARAP.

    python bench/deform.py [--steps 1500] [--resolution 224] [--refit] [--arap-iters 100]

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
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from bench._harness import Bench, cached_run_fit  # noqa: E402

BAR_DIR = ROOT / ".cache/bench/deform/bars"
RESULTS = ROOT / "bench/results"
CREATURE = "creature_0000"
BOUND = 1.25            # extraction grid [-1.25, 1.25]^3: bent bars leave the unit cube
FIXED_T = 0.1           # the handle GC's own start region that stays (t <= 0.1)

# the bar: 1.6 long along x (already in the normalised frame: longest side 2 x 0.8), square
# cross-section 0.2 x 0.2 with rounded edges; one straight GC from x = -0.7 to 0.7
BAR_HALF = (0.8, 0.1, 0.1)
BAR_ROUND = 0.025


# ---- inputs ----------------------------------------------------------------------------------
def make_bar(out_dir: Path = BAR_DIR, spacing: float = 0.016) -> Path:
    """A watertight rounded square bar (marching cubes of its SDF) and its one-GC annotation;
    written once. Returns the annotation path."""
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
def rotation(axis, degrees) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    a = np.asarray(axis, float)
    return Rotation.from_rotvec(a / np.linalg.norm(a) * math.radians(degrees)).as_matrix()


@dataclass
class Case:
    """A handle drag: the vertices of `gc` over t in `at` move by a rigid motion.

    bend: the piece of the GC between t = FIXED_T and t = at[0] is wrapped onto a circular arc
    of `degrees` turning toward `up` (its chord direction d, the arc in the plane of d and up),
    and the handle region follows the arc's end rigidly: a constant-curvature bend, the
    motion an arc-length preserving deformation can meet. twist: the handles turn about the
    GC's axis (its chord)."""

    name: str
    shape: str
    gc: str
    kind: str                 # bend | twist
    degrees: float
    at: tuple = (0.9, 1.0)
    up: tuple = (0.0, 0.0, 1.0)
    picture: bool = False

    def motion(self, gc) -> tuple[np.ndarray, np.ndarray]:
        """(R, t): handle targets are H @ R.T + t."""
        p_f, p_h = gc.to_world(np.array([[2 * FIXED_T - 1, 0, 0], [2 * self.at[0] - 1, 0, 0]]))
        chord = p_h - p_f
        d = chord / np.linalg.norm(chord)
        if self.kind == "twist":
            return rotation(d, self.degrees), p_h - rotation(d, self.degrees) @ p_h
        if self.kind != "bend":
            raise ValueError(self.kind)
        n = np.asarray(self.up, float) - (np.asarray(self.up, float) @ d) * d
        n /= np.linalg.norm(n)
        th = math.radians(self.degrees)
        rho = np.linalg.norm(chord) / th
        R = rotation(np.cross(d, n), self.degrees)  # turns d toward n
        P = p_f + rho * math.sin(th) * d + rho * (1 - math.cos(th)) * n
        return R, P - R @ p_h


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


def constraints(case: Case, gcs, V):
    """Handle and fixed vertex indices of the input mesh (disjoint). The handle GC's part is
    the vertices inside it or, outside every GC, nearest to it; the fixed vertices are the rest
    of the mesh plus the part's start region t <= FIXED_T."""
    from ngc_gen.edit.program import region_mask

    rel = np.stack([g.to_relative(V) for g in gcs])  # (K, N, 3)
    measure = np.clip(np.abs(rel[..., 0]) - 1, 0, None) ** 2 + rel[..., 1] ** 2 + rel[..., 2] ** 2
    k = [g.name for g in gcs].index(case.gc)
    gc = gcs[k]
    part = (measure[k] <= 1.0) | (measure.argmin(0) == k)
    handle = part & region_mask(gc, V, case.at)
    fixed = (~part | region_mask(gc, V, (0.0, FIXED_T))) & ~handle
    return np.flatnonzero(handle), np.flatnonzero(fixed)


def arap(V, F, handle, fixed, targets, iters: int) -> tuple[np.ndarray, float]:
    """libigl ARAP with handles moved and fixed vertices pinned; one pinned vertex for every
    connected piece without a constraint. Returns (deformed vertices, seconds)."""
    import igl
    import trimesh

    t0 = time.perf_counter()
    b = np.concatenate([handle, fixed])
    bc = np.concatenate([targets, V[fixed]])
    labels = trimesh.graph.connected_component_labels(trimesh.Trimesh(V, F, process=False)
                                                      .face_adjacency, node_count=len(F))
    vlab = np.full(len(V), -1)
    vlab[F.reshape(-1)] = np.repeat(labels, 3)
    free = sorted(set(vlab[vlab >= 0].tolist()) - set(vlab[b].tolist()))
    extra = np.array([np.flatnonzero(vlab == p)[0] for p in free], dtype=np.int64)
    b = np.concatenate([b, extra]).astype(np.int64)
    bc = np.concatenate([bc, V[extra]]) if len(extra) else bc
    data = igl.ARAPData()
    data.max_iter = int(iters)
    igl.arap_precomputation(V, F, 3, b, data)
    U = igl.arap_solve(np.ascontiguousarray(bc), data, V.copy())
    return U, time.perf_counter() - t0


def edit_to_mesh(case: Case, shape, gcs, R, t, handles, targets, fixed_pts, resolution: int,
                 arap_iters: int, undeformed: dict, arap_at: int = 256):
    """Seconds from handle targets to the edited mesh at `resolution`, the interactive loop:
    the handle solve plus the incremental extraction (the undeformed shape was extracted
    before, untimed, so its per-GC values sit in shape.cache and only the GCs the solve moved
    are evaluated again); the solve gets the same handles as the case. At `arap_at` also
    returns (ARAP seconds, vertex count): libigl ARAP with the same handle region and motion
    on that undeformed NGC mesh (a mesh of NGC's vertex count), else None."""
    import torch

    from ngc_gen.edit import deform_by_handles

    key = (case.shape, resolution)
    with torch.inference_mode():
        if key not in undeformed:
            undeformed[key] = shape.mesh(resolution, BOUND).mesh
        before = undeformed[key]
        t0 = time.perf_counter()
        new = deform_by_handles(gcs, handles, targets, fixed_pts)
        shape.replaced(gcs=new).mesh(resolution, BOUND)
        seconds = time.perf_counter() - t0
    arap_matched = None
    if resolution == arap_at:
        V = np.asarray(before.vertices, dtype=np.float64)
        F = np.asarray(before.faces, dtype=np.int64)
        handle, fixed = constraints(case, gcs, V)
        _, arap_s = arap(V, F, handle, fixed, V[handle] @ R.T + t, arap_iters)
        arap_matched = (arap_s, int(len(V)))
    return seconds, arap_matched


def run_case(case: Case, module, shape_index: dict, inputs: dict, resolution: int,
             arap_iters: int, undeformed: dict, matched: tuple = ()) -> dict:
    import torch
    import trimesh

    from ngc_gen.edit import deform_by_handles
    from ngc_gen.edit.ops import curve_points_at
    from ngc_gen.eval import volume_area_change
    from ngc_gen.shape import Shape, recorded_gcs

    meta = module.hparams.meta["shapes"][shape_index[case.shape]]
    gcs = recorded_gcs(meta)
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]].detach()
    V, F = inputs[case.shape]
    handle, fixed = constraints(case, gcs, V)
    gc = next(g for g in gcs if g.name == case.gc)
    R, t = case.motion(gc)
    targets = V[handle] @ R.T + t

    # one Shape per input shape, so its FieldCache carries the undeformed values across cases
    shape = undeformed.setdefault(("shape", case.shape),
                                  Shape(gcs, codes, module.decoder, name=case.shape))
    with torch.no_grad():
        if case.shape not in undeformed:
            undeformed[case.shape] = shape.mesh(resolution, BOUND).mesh
        before = undeformed[case.shape]
        # the fixed region for NGC: the fixed vertices plus the skeletons of the other GCs (a
        # part rooted inside the fixed body, like a tail in a torso, is far from its surface)
        skeleton = [curve_points_at(g, np.linspace(0, 1, 33)) for g in gcs if g.name != case.gc]
        fixed_pts = np.concatenate([V[fixed], *skeleton])
        t0 = time.perf_counter()
        new, info = deform_by_handles(gcs, V[handle], targets, fixed_pts, return_info=True)
        solve_s = time.perf_counter() - t0
        after = shape.replaced(gcs=new).mesh(resolution, BOUND).mesh
        ngc_s = time.perf_counter() - t0
    # where the handle GC carries the handle vertices (their relative coordinates)
    new_gc = next(g for g in new if g.name == case.gc)
    carried = new_gc.to_world(gc.to_relative(V[handle]))
    ngc = {**volume_area_change(before, after), "time_s": ngc_s, "solve_s": solve_s,
           "handle_err": float(np.linalg.norm(carried - targets, axis=1).max()),
           "bent": sorted(info.bent), "followers": sorted(info.followers)}

    for res in matched:  # edit-to-mesh at 128 / 256, ARAP on a mesh of NGC's vertex count
        ngc[f"edit_to_mesh_s_{res}"], arap_matched = edit_to_mesh(
            case, shape, gcs, R, t, V[handle], targets, fixed_pts, res, arap_iters, undeformed)
        if arap_matched is not None:
            ngc["arap_s_matched"], ngc["arap_matched_vertices"] = arap_matched

    U, arap_s = arap(V, F, handle, fixed, targets, arap_iters)
    m0 = trimesh.Trimesh(V, F, process=False)
    m1 = trimesh.Trimesh(U, F, process=False)
    res = {"name": case.name, "ngc": ngc,
           "arap": {**volume_area_change(m0, m1), "time_s": arap_s,
                    "handle_err": float(np.linalg.norm(U[handle] - targets, axis=1).max())},
           "n_handles": int(len(handle)), "n_fixed": int(len(fixed)), "n_vertices": int(len(V)),
           "degrees": case.degrees, "kind": case.kind, "gc": case.gc, "shape": case.shape}
    res["_meshes"] = (m0, before, after, m1)
    res["_focus"] = (np.minimum(gc.bounds()[0], new_gc.bounds()[0]),
                     np.maximum(gc.bounds()[1], new_gc.bounds()[1]))
    return res


def mean_of(cases: list[dict]) -> dict:
    keys = {"ngc": ("eps_v", "eps_a", "time_s", "solve_s"), "arap": ("eps_v", "eps_a", "time_s")}
    return {m: {k: float(np.mean([c[m][k] for c in cases])) for k in ks}
            for m, ks in keys.items()}


def matched_means(cases: list[dict]) -> dict:
    """edit_to_mesh_s_<res> and arap_s_matched, means over the cases that measured them."""
    keys = sorted({k for c in cases for k in c["ngc"]
                   if k.startswith("edit_to_mesh_s_") or k == "arap_s_matched"})
    return {k: float(np.mean([c["ngc"][k] for c in cases if k in c["ngc"]])) for k in keys}


def picture(results: list[dict], path: Path, cell=(330, 250)) -> None:
    """Rows of cases, columns NGC before / NGC after / ARAP after; one camera per row, aimed at
    the handle GC before and after, so before and after compare directly. pyvista off screen
    (EGL)."""
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

    from bench.report import table
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
    print(table("deform", json.loads(path.read_text())))


if __name__ == "__main__":
    main()
