"""bench/seams.py's edited shapes and close-ups: the junction measure after a shipped edit
program, and the worst junction of each shape seen close up (truth, before, after)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: width of the weights that carry the truth's vertices along an edit (as the blend's fade)
CARRY_WIDTH = 0.25


def edited_truth(truth, gcs: list, edited: list):
    """The true mesh moved by an edit of its GCs: each vertex at its relative coordinates in
    every GC holding it, mapped to the world by the edited GC, the positions averaged with the
    blended union's weights (`fade_weight`); a vertex no GC holds follows the GC it is
    relatively nearest to (the edit's own map, as the fit's field moves)."""
    import trimesh

    from ngc_gen.geometry import fade_weight

    V = np.asarray(truth.vertices, dtype=np.float64)
    num, den = np.zeros_like(V), np.zeros(len(V))
    best, best_m = np.zeros_like(V), np.full(len(V), np.inf)
    for gc, new in zip(gcs, edited):   # a loop over the GCs, never over points
        rel, m = gc.relative_inside(V, cull=False)
        moved = np.asarray(new.to_world(rel), dtype=np.float64)
        w = np.where(m <= 1.0, fade_weight(m, CARRY_WIDTH), 0.0)
        num += w[:, None] * moved
        den += w
        nearer = m < best_m
        best[nearer], best_m[nearer] = moved[nearer], m[nearer]
    held = den > 0
    out = best.copy()
    out[held] = num[held] / den[held][:, None]
    return trimesh.Trimesh(out, np.asarray(truth.faces), process=False)


def edit_rows(programs: dict, runs: dict, rows: list[dict], resolution: int,
              unions: dict) -> list[dict]:
    """Per shape with a program and per recipe: the junction ratios of the edited fit (its
    shape with that recipe's union, `unions`: recipe -> Shape keyword arguments) against the
    edited truth, and their change from the same fit's unedited ratios (`rows`)."""
    import yaml

    from bench._seams import truth_and_gcs
    from ngc_gen.edit.program import EditProgram
    from ngc_gen.eval import junction_metrics
    from ngc_gen.shape import load_shapes

    out = []
    for name, program in programs.items():
        path = ROOT / "ngc_gen/conf/edit" / f"{program}.yaml"
        prog = EditProgram.from_dict(yaml.safe_load(path.read_text()), str(path))
        for recipe in ("before", "after"):
            run_dir = runs.get((name, recipe))
            if run_dir is None:
                continue
            cached = run_dir / f"edit_{program}_{recipe}.json"
            if cached.exists():
                out.append(json.loads(cached.read_text()))
                continue
            truth, gcs = truth_and_gcs(run_dir, name)
            shape = load_shapes(run_dir / "checkpoints" / "last.ckpt")[name]
            edited = shape.replaced(**unions[recipe]).edited(prog)
            mesh = edited.mesh(resolution).mesh
            m = junction_metrics(mesh, edited_truth(truth, gcs, edited.gcs), edited.gcs)
            base = next(r for r in rows if r["name"] == name and r["recipe"] == recipe)
            rec = {"name": name, "recipe": recipe, "program": program,
                   "junction_ratio_dist": m["junction_ratio_dist"],
                   "junction_ratio_normal": m["junction_ratio_normal"],
                   "extra_pieces": m["extra_pieces"],
                   "change_dist": m["junction_ratio_dist"] / base["junction_ratio_dist"] - 1,
                   "change_normal": (m["junction_ratio_normal"]
                                     / base["junction_ratio_normal"] - 1)}
            cached.write_text(json.dumps(rec))
            out.append(rec)
    return out


def picture(rows: list[dict], runs: dict, path: Path, radius: float) -> Path | None:
    """Per shape, its worst junction (the `before` fit's, where the seam shows) close up:
    truth, before, after cropped around the same point, seen along the truth's normal there."""
    import trimesh

    from bench._seams import crop, facing, truth_and_gcs
    from ngc_gen.eval.junctions import worst_junction
    from ngc_gen.viz import render_grid

    cells, labels, views = [], [], []
    for name in dict.fromkeys(r["name"] for r in rows):
        before, after = runs.get((name, "before")), runs.get((name, "after"))
        if before is None or after is None:
            continue
        truth, gcs = truth_and_gcs(before, name)
        meshes = [trimesh.load(before / "meshes" / f"{name}{tail}.ply", process=False)
                  for tail in ("", "_after")]     # `after` meshes the same fit: seams.blended
        found = worst_junction(meshes[0], truth, gcs, radius / 2)
        if found is None:
            continue
        centre, _ = found
        cells.append([crop(m, centre, radius) for m in (truth, *meshes)])
        labels.append(name)
        views.append(facing(truth, centre))
    if not cells:
        return None
    return render_grid(cells, path, labels=labels, frame="row", cell=(260, 220), view=views,
                       col_titles=["truth", "before (min)", "after (blend)"])
