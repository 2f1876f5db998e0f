"""Seams benchmark (run by bench/fit.py --junctions): real and procedural meshes, each fitted
on its own as a user fits one asset (train.py stage=fit, the default recipe, one thread),
scored where GCs meet against elsewhere (ngc_gen.eval.junctions), before and after the seam
remedies and against DeepSDF.

    python bench/fit.py --junctions [--recipes before after deepsdf] [--only ant_auto cow_rig]
                        [--fit-workers 2] [--steps N]

Meshes (rest poses; `MESHES`): pyvista's ant and airplane, 8 training creatures, 6 animals;
each with automatic GCs (`auto`: only the triangles go in) and with its own GCs where it has
them (`annotated`: the ant's and airplane's hand annotation, the creatures' parts; `rig`: the
animals' GCs from their rig). A mesh is staged as a folder of one mesh (and its GC YAML for
annotated / rig) and fitted with `data=folder`.

Recipes (`RECIPES`): `before` (the seam remedies off: no pair margin, no junction weight:
today's defaults), `after` (the remedy under test; docs/fitting.md "Seams"), `deepsdf` (the single-network reference, model=deepsdf_small on
DeepSDF's box sampling, scored at the same GCs) with its steps scaled so its training takes
about the time of NGC's: NGC's over DeepSDF's training seconds per step at the same batch,
from bench/results/fit.json's `methods` (written by bench/fit.py at equal steps).

Every fit goes through the bench's fit cache (bench/_harness.py `FitCache("junctions")`):
rerun the command to fill in what is missing; fits run `--fit-workers` side by side.
Rows go to bench/results/fit.json `junctions` = [{name, gcs, recipe, method,
junction_ratio_dist, junction_ratio_normal, extra_pieces, nc, fscore, train_s, steps}; the
`before` entry also carries `ceiling`: the same figures of the mesh's exact SDF meshed at the
fit's resolution, what the grid allows there], and
bench/results/fit_junctions.png shows the worst junctions close up (truth, before, after,
DeepSDF).
"""
from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from bench._harness import FitCache, config_recipe, file_identity, train_subprocess

ROOT = Path(__file__).resolve().parents[1]

STAGED = ROOT / ".cache/bench/junction_meshes"
CREATURES = 8
ANIMALS = ("alpaca", "bull", "deer", "fox", "horse", "wolf")
RECIPES = {   # name -> overrides of train.py stage=fit
    "before": ["prepare.pair_margin=0.0", "junction_weight=0.0"],
    "after": ["prepare.pair_margin=0.1"],   # not the default: see docs/fitting.md "Seams"
    "deepsdf": ["model=deepsdf_small", "prepare.volume_region=box"],
}
CLOSEUP = 0.08   # radius of a close-up around the worst junction (normalised units: box 1.6)


def sources() -> list[tuple[str, str, object]]:
    """(name, gcs, annotation) of every bench mesh with its own GCs, the automatic entries
    (same mesh, gcs `auto`) added by `staged`."""
    from hydra.utils import instantiate

    from ngc_gen.app.runtime.config import compose_config

    out = []
    for data in ("ant", "airplane"):
        ann = instantiate(compose_config(overrides=[f"data={data}"]).data).shapes()[0]
        out.append((data, "annotated", ann))
    creatures = compose_config(overrides=["data=creatures", f"data.limit={CREATURES}"]).data
    out += [(a.name, "annotated", a) for a in instantiate(creatures).shapes()]
    animals = compose_config(overrides=[
        "data=animals", "data.frames=2", "data.split=rest", f"data.species=[{','.join(ANIMALS)}]",
        "data.heldout_species=[]", "data.heldout_clips_by_species=null"]).data
    out += [(a.name.removesuffix("_rest"), "rig", a) for a in instantiate(animals).shapes()]
    return out


def staged() -> list[tuple[str, str, Path]]:
    """(name, gcs, folder) per bench entry: a folder holding the mesh as <stem>.ply and, for
    annotated / rig GCs, <stem>.yaml beside it (the annotation with its mesh made local)."""
    import trimesh
    import yaml

    from ngc_gen.data.atomic import atomic_write, atomic_write_text
    from ngc_gen.data.mesh.io import load_mesh

    out = []
    for name, gcs, ann in sources():
        for kind in (gcs, "auto"):
            folder = STAGED / f"{name}_{kind}"
            mesh = folder / f"{name}.ply"
            if not mesh.exists():
                folder.mkdir(parents=True, exist_ok=True)
                m = load_mesh(ann.mesh_path)
                plain = trimesh.Trimesh(m.vertices, m.faces, process=False)
                atomic_write(mesh, lambda f: f.write(plain.export(file_type="ply")))
            if kind != "auto":
                d = ann.to_dict()
                d["mesh"], d["name"] = mesh.name, name   # the auto entry's shape name
                text = yaml.safe_dump(d, sort_keys=False)
                target = folder / f"{name}.yaml"
                if not target.exists() or target.read_text() != text:
                    atomic_write_text(target, text)
            out.append((name, kind, folder))
    return out


def time_ratio() -> float:
    """DeepSDF's steps per NGC step for equal training time: NGC's over DeepSDF's training
    seconds at equal steps and batch (bench/results/fit.json `methods`); 1 without it."""
    path = ROOT / "bench/results/fit.json"
    try:
        m = json.loads(path.read_text())["methods"]
        return float(m["ngc"]["train_s"]) / float(m["deepsdf"]["train_s"])
    except (FileNotFoundError, KeyError, ValueError, ZeroDivisionError):
        return 1.0


def fit_overrides(name: str, folder: Path, recipe: str, steps: int) -> list[str]:
    n = max(1, round(steps * time_ratio())) if recipe == "deepsdf" else steps
    return ["stage=fit", "data=folder", f"data.path={folder}", f"trainer.max_steps={n}",
            "trainer.enable_progress_bar=false", "logger=csv", *RECIPES[recipe],
            f"prepare.cache_dir={ROOT}/.cache/prepared/junctions/{recipe}/{folder.name}"]


def fit_one(cache: FitCache, name: str, gcs: str, folder: Path, recipe: str,
            steps: int, refit: bool = False):
    """One mesh, one recipe: a cached train.py run in its own process (one thread)."""
    from ngc_gen.app.runtime.config import compose_config

    over = fit_overrides(name, folder, recipe, steps)
    cfg = compose_config(overrides=over)

    def fit(run_dir: Path) -> dict:
        wall = train_subprocess(over, run_dir, f"the fit of {name} ({gcs} GCs, {recipe})")
        return {"wall_s": wall, "label": f"{name}/{gcs}/{recipe}"}

    f = cache.get({"stage": "junction_fit", "config": config_recipe(cfg),
                   "data": file_identity([folder])}, fit, refit=refit)
    print(f"{name} ({gcs} GCs, {recipe}) {'cached' if f.reused else 'fitted'}: {f.run_dir}",
          flush=True)
    return f


def exact_sdf_mesh(vertices: np.ndarray, faces: np.ndarray, resolution: int):
    """The mesh's own exact signed distance meshed at `resolution` over [-1, 1]^3 (coarse to
    fine: it is 1-Lipschitz): what a grid of that size allows a fit to reach."""
    import torch

    from ngc_gen.data.mesh.sdf import signed_distance, solid_surface
    from ngc_gen.extract.world import extract_world_mesh

    solid = solid_surface(vertices, faces)   # the solid's own SDF, as fits learn it

    def exact(x):
        return torch.from_numpy(signed_distance(x.double().numpy(), vertices, faces,
                                                distance_mesh=solid)).float()

    return extract_world_mesh(exact, resolution, 1.0, coarse_step=4, lipschitz=1.0).mesh


#: the junction figures a ceiling records (ngc_gen.eval.junctions)
CEILING_KEYS = ("junction_ratio_dist", "junction_ratio_normal", "junction_ratio_dist_local",
                "junction_ratio_normal_local", "junction_dist", "elsewhere_dist",
                "junction_normal_deg", "elsewhere_normal_deg", "extra_pieces")


def ceiling(run_dir: Path, name: str, resolution: int) -> dict:
    """What the grid allows on this mesh and GCs: its exact signed distance meshed at the fit's
    resolution and scored like a fit (marching cubes rounds the creases where parts meet, and
    thin sheets break), cached beside the run as ceiling.json."""
    path = run_dir / "ceiling.json"
    if path.exists():
        cached = json.loads(path.read_text())
        if set(CEILING_KEYS) <= set(cached):   # else written before a figure was added
            return cached
    from ngc_gen.eval import junction_metrics, reconstruction_metrics

    truth, gcs = truth_and_gcs(run_dir, name)
    mesh = exact_sdf_mesh(np.asarray(truth.vertices), np.asarray(truth.faces), resolution)
    m = {**reconstruction_metrics(mesh, truth), **junction_metrics(mesh, truth, gcs)}
    out = {**{k: m[k] for k in CEILING_KEYS if k in m}, "nc": m["normal_consistency"],
           "fscore": m["fscore"], "resolution": resolution}
    path.write_text(json.dumps(out))
    return out


def row(name: str, gcs: str, recipe: str, run_dir: Path) -> dict:
    """fit.json `junctions` entry of one fit run (its metrics.json)."""
    m = json.loads((run_dir / "metrics.json").read_text())
    s = m["shapes"][name]
    return {"name": name, "gcs": gcs, "recipe": recipe,
            "method": "deepsdf" if recipe == "deepsdf" else "ngc",
            "junction_ratio_dist": s["junction_ratio_dist"],
            "junction_ratio_normal": s["junction_ratio_normal"],
            "extra_pieces": s["extra_pieces"], "nc": s["normal_consistency"],
            "fscore": s["fscore"], "train_s": m["train_s"], "steps": m["steps"]}


def run(recipes: list[str], only: list[str] | None, workers: int, steps: int | None,
        refit: bool = False) -> tuple[list[dict], dict]:
    """Fit what is missing; -> (rows, {(name, gcs, recipe): run_dir})."""
    from ngc_gen.app.runtime.config import compose_config

    steps = steps or int(compose_config(overrides=["stage=fit"]).trainer.max_steps)
    cache = FitCache("junctions")
    jobs = [(n, g, folder, r) for n, g, folder in staged() for r in recipes
            if not only or f"{n}_{g}" in only or n in only]
    # before and after of a mesh side by side, so a stopped run leaves comparable pairs
    with ThreadPoolExecutor(max(1, workers)) as pool:
        fits = list(pool.map(lambda j: fit_one(cache, *j, steps, refit), jobs))
    runs = {(n, g, r): f.run_dir for (n, g, _, r), f in zip(jobs, fits)}
    rows = [row(n, g, r, d) for (n, g, r), d in runs.items()]
    from omegaconf import OmegaConf

    for r, d in zip(rows, runs.values()):
        if r["recipe"] == "before":   # the mesh's ceiling, once per mesh and GCs
            resolution = int(OmegaConf.load(d / "config.yaml").extract.resolution)
            r["ceiling"] = ceiling(d, r["name"], resolution)
    return rows, runs


def truth_and_gcs(run_dir: Path, name: str):
    """(the normalised true mesh, its GCs) a fit run was scored against: its prepared shape."""
    import trimesh
    from omegaconf import OmegaConf

    from ngc_gen.data.prepare import cache_path, load_prepared

    cfg = OmegaConf.load(run_dir / "config.yaml")
    prep = load_prepared(cache_path(moved_cache(Path(cfg.prepare.cache_dir)), name))
    return trimesh.Trimesh(prep.mesh_vertices, prep.mesh_faces, process=False), prep.gcs()


def moved_cache(recorded: Path) -> Path:
    """A run's recorded prepared-sample folder, or the same folder under this checkout's
    .cache when the run was fitted from another checkout that shares the cache (and is gone)."""
    parts = recorded.parts
    if recorded.exists() or ".cache" not in parts:
        return recorded
    return ROOT.joinpath(*parts[parts.index(".cache"):])


def labelled_runs() -> dict:
    """{(name, gcs, recipe): run_dir} of every seams fit in the cache, the newest of each
    (close-ups of entries that earlier runs fitted)."""
    out = {}
    for f in FitCache("junctions").entries():   # oldest first: newer ones overwrite
        label = str(f.info.get("label") or "")
        if label.count("/") == 2 and (f.run_dir / "metrics.json").is_file():
            out[tuple(label.split("/"))] = f.run_dir
    return out


def merge_rows(old: list[dict], new: list[dict]) -> list[dict]:
    """fit.json `junctions` after a partial run: the new entries, and the old ones of every
    (mesh, GCs, recipe) the run did not fit, in a fixed order."""
    mine = {(r["name"], r["gcs"], r["recipe"]) for r in new}
    kept = [r for r in old if (r["name"], r["gcs"], r["recipe"]) not in mine]
    order = {r: i for i, r in enumerate(RECIPES)}   # before, after, deepsdf
    return sorted(kept + new, key=lambda r: (r["name"], r["gcs"], order.get(r["recipe"], 99)))


def crop(mesh, centre: np.ndarray, radius: float):
    """The faces of `mesh` with a corner within `radius` of `centre` (a close-up); a coarse
    mesh (a low-poly truth) is first split into edges under radius / 8, so its close-up
    ends about where a fine one does."""
    import trimesh

    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    tri = v[f]
    reach = np.linalg.norm(tri - tri.mean(1, keepdims=True), axis=2).max(1)
    f = f[np.linalg.norm(tri.mean(1) - centre, axis=1) <= radius + reach]
    if len(f) and np.linalg.norm(v[f] - v[np.roll(f, 1, axis=1)], axis=2).max() > radius / 8:
        v, f = trimesh.remesh.subdivide_to_size(v, f, max_edge=radius / 8)
    near = np.linalg.norm(v - centre, axis=1) <= radius
    faces = f[near[f].any(1)]
    used, inverse = np.unique(faces, return_inverse=True)   # only the vertices it shows
    return trimesh.Trimesh(v[used], inverse.reshape(-1, 3), process=False)


def facing(truth, centre: np.ndarray) -> np.ndarray:
    """(3,) the normal of the truth's face nearest `centre`: the close-up's view direction."""
    import igl  # libigl: trimesh's nearest face would need rtree

    _, tri, _ = igl.point_mesh_squared_distance(
        centre[None], np.asarray(truth.vertices, dtype=np.float64),
        np.asarray(truth.faces, dtype=np.int64))
    return np.asarray(truth.face_normals[int(tri[0])])


def picture(rows: list[dict], runs: dict, path: Path, n: int = 4) -> Path | None:
    """The `n` worst junctions of the `before` recipe, close up: truth, before, after, DeepSDF
    cropped around the same point, seen along the truth's normal there."""
    import trimesh

    from ngc_gen.eval.junctions import worst_junction
    from ngc_gen.viz import render_grid

    before = sorted((r for r in rows if r["recipe"] == "before"
                     and r["junction_ratio_dist"] is not None),
                    key=lambda r: -max(r["junction_ratio_dist"], r["junction_ratio_normal"]))
    cells, labels, views = [], [], []
    for r in before[:n]:
        run_dir = runs.get((r["name"], r["gcs"], "before"))
        if run_dir is None:   # fitted elsewhere: no run here to look at
            continue
        truth, gcs = truth_and_gcs(run_dir, r["name"])
        fitted = trimesh.load(run_dir / "meshes" / f"{r['name']}.ply", process=False)
        found = worst_junction(fitted, truth, gcs, CLOSEUP / 2)
        if found is None:
            continue
        centre, _ = found
        row_ = [crop(truth, centre, CLOSEUP), crop(fitted, centre, CLOSEUP)]
        for other in ("after", "deepsdf"):
            d = runs.get((r["name"], r["gcs"], other))
            row_.append(crop(trimesh.load(d / "meshes" / f"{r['name']}.ply", process=False),
                             centre, CLOSEUP) if d is not None else None)
        cells.append(row_)
        labels.append(f"{r['name']} ({r['gcs']})")
        views.append(facing(truth, centre))
    if not cells:
        return None
    return render_grid(cells, path, labels=labels, frame="row", cell=(260, 220), view=views,
                       col_titles=["truth", "before", "after", "DeepSDF"])
