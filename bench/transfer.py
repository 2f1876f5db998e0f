"""Template transfer against ground truth (docs/transfer.md): writes bench/results/transfer.json.

animals: the posed animals of `data=animals` (frames=1: 12 species x 9 clips = 108 meshes), the
rig withheld: only each shape's triangles (its .ply) go in, with the collection's axes given
(y up, +z front, as the user of this collection knows them), against datasets/animals/quadruped_transfer.yaml. Per template GC: purity = the share
of its rig-GC surface samples (a sample belongs to the rig GC it is relatively nearest to) inside
the transferred GC of the same name, averaged over the matched meshes; endpoint error = distance
of each curve end from the rig GC's, over the rig GC's arc length (median over GCs, ends and
meshes); matched = share of meshes not refused; s_per_mesh = median transfer seconds (the mean,
with each process's first mesh compiling its kernels, in details).
creatures: a template exported from the true GCs of the first 8 built creatures (z up, +x front), transferred
onto the next 24 written as plain meshes; purity against their true GCs.
refused: which of a chair, a torus and a sphere the quadruped template refuses.
generator: not measured by this bench (null).

    python bench/transfer.py [--limit N] [--workers W]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench._harness import Bench  # noqa: E402

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
SAMPLES = 20000


def _truth_scores(truth_gcs, gcs, points):
    """(purity (G,), endpoint errors (2G,)) of transferred GCs against true GCs, same order."""
    import numpy as np

    from ngc_gen.data.autogc.coverage import rho_matrix
    from ngc_gen.data.mesh.sampling import gc_membership

    part = rho_matrix(truth_gcs, points)[0].argmin(0)
    pp, pg, _ = gc_membership(points, gcs)
    inside = np.zeros((len(points), len(gcs)), bool)
    inside[pp, pg] = True
    purity = np.array([inside[part == g, g].mean() if (part == g).any() else np.nan
                       for g in range(len(truth_gcs))])
    line = np.stack([np.linspace(-1, 1, 65), np.zeros(65), np.zeros(65)], 1)
    errs = []
    for t, g in zip(truth_gcs, gcs):
        ct, cg = np.asarray(t.to_world(line)), np.asarray(g.to_world(line))
        length = np.linalg.norm(np.diff(ct, axis=0), axis=1).sum()
        errs += [np.linalg.norm(ct[0] - cg[0]) / length, np.linalg.norm(ct[-1] - cg[-1]) / length]
    return purity, np.array(errs)


def one(task):
    """Worker: transfer onto one mesh file; scores against its annotation's GCs."""
    import numpy as np
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
    from ngc_gen.data.errors import DataError
    from ngc_gen.data.mesh.sampling import sample_surface

    name, ply, truth_yaml, template_path, axes = task
    mesh = trimesh.load(ply, process=False)
    template = load_template(template_path)
    settings = TransferSettings(**axes)
    t0 = time.perf_counter()
    try:
        tr = transfer_template(mesh, template, settings, name)
    except DataError as e:
        return {"mesh": name, "error": str(e), "seconds": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    out = {"mesh": name, "seconds": seconds, "missing": tr.missing, "cost": tr.cost,
           "coverage": tr.coverage}
    if truth_yaml:
        truth = load_annotation(truth_yaml)
        pts, _ = sample_surface(mesh.vertices, mesh.faces, SAMPLES, np.random.default_rng(1))
        # the true GCs of the template's parts, by name (the rig template has GCs the transfer
        # template has not: the antlers carved out of the head count as the head's here)
        by_name = {g.name: g for g in truth.gcs}
        purity, errs = _truth_scores([by_name[g.name] for g in tr.gcs], tr.gcs, pts)
        out.update(purity=[float(p) for p in purity], endpoint_err=[float(e) for e in errs])
    return out


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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=int, default=None, help="posed animals (default: all 108)")
    ap.add_argument("--creatures", type=int, default=24)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    bench = Bench("transfer")
    import numpy as np
    import trimesh
    import yaml

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.data.autogc.orient import Orientation
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import export_template
    from ngc_gen.data.mesh.sampling import sample_surface
    from ngc_gen.data.rigs.animals import Animals
    from ngc_gen.data.workers import map_shapes

    conf = yaml.safe_load((ROOT / "conf/data/animals.yaml").read_text())
    conf = {k: v for k, v in conf.items() if not k.startswith("_")}
    conf.update(template=str(ROOT / "datasets/animals/quadruped.yaml"), rigs_dir=str(ROOT / ".cache/rigs"),
                out_dir=str(ROOT / ".cache/datasets/animals_f1"), frames=1, split="all",
                limit=args.limit, workers=args.workers)
    records = Animals(**conf).build()
    template = load_template(TEMPLATE)
    axes = {"up": "+y", "front": "+z"}
    tasks = [(r["name"], r["mesh"], r["annotation"], str(TEMPLATE), axes) for r in records]
    rows = list(map_shapes(one, tasks, args.workers, min_items=4))
    animals = _summary(rows, template.names)
    animals["missing_counts"] = {n: sum(n in r.get("missing", []) for r in rows) for n in template.names}
    # creatures: a template from the true GCs of the first 8, transferred onto the next ones
    cdir = ROOT / ".cache/datasets/creatures_n64_s0"
    z_up = Orientation(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), ("given", "given"))
    have = sorted(p.stem for p in cdir.glob("creature_*.yaml") if p.with_suffix(".ply").is_file())
    shapes = []
    for stem in have[:8]:
        ann = load_annotation(cdir / f"{stem}.yaml")
        m = trimesh.load(cdir / f"{stem}.ply", process=False)
        pts, _ = sample_surface(m.vertices, m.faces, SAMPLES, np.random.default_rng(0))
        shapes.append((ann.gcs, pts, z_up))
    ctemplate = export_template(shapes, "creature")
    cpath = ROOT / "bench/results/transfer_creature_template.yaml"
    atomic_write_text(cpath, ctemplate.to_yaml())
    ctasks = [(stem, str(cdir / f"{stem}.ply"), str(cdir / f"{stem}.yaml"), str(cpath),
               {"up": "+z", "front": "+x"}) for stem in have[8:8 + args.creatures]]
    crows = list(map_shapes(one, ctasks, args.workers, min_items=4))
    creatures = _summary(crows, ctemplate.names)
    # meshes of another kind
    from tests.data.autogc.shapes import chair, sphere, torus
    from ngc_gen.data.mesh.io import normalize

    refused, errors, tmp = [], {}, ROOT / ".cache/bench/transfer"
    tmp.mkdir(parents=True, exist_ok=True)
    for make in (chair, torus, sphere):
        m, _, _ = normalize(make())
        m.export(tmp / f"{make.__name__}.ply")
        r = one((make.__name__, str(tmp / f"{make.__name__}.ply"), None, str(TEMPLATE), {}))
        if "error" in r:
            refused.append(make.__name__)
            errors[make.__name__] = r["error"]
    result = {
        "animals": {k: animals[k] for k in ("n", "matched", "purity_mean", "purity_worst",
                                            "endpoint_err_median", "s_per_mesh")},
        "creatures": {"n": creatures["n"], "purity_mean": creatures["purity_mean"]},
        "generator": {"rig": {"mmd_cd": None, "nna_cd": None},
                      "transferred": {"mmd_cd": None, "nna_cd": None}},
        "refused": refused,
        "details": {"animals": {k: animals[k] for k in ("purity_per_gc", "missing_counts",
                                                         "s_per_mesh_mean")},
                    "creatures": {k: creatures[k] for k in ("matched", "purity_worst", "purity_per_gc",
                                                             "endpoint_err_median", "s_per_mesh")},
                    "template": str(TEMPLATE.relative_to(ROOT)),
                    "refused_errors": errors,
                    "per_mesh": rows},
    }
    print(bench.write(result))
    print({k: result[k] for k in ("animals", "creatures", "refused")})


if __name__ == "__main__":
    main()
