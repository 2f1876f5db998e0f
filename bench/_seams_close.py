"""bench/seams.py's edited shapes and close-ups: the junction measure after a shipped edit
program, and the worst junction of each shape seen close up (truth, before, after)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: width of the weights that carry the truth's vertices along an edit (as the blend's fade)
CARRY_WIDTH = 0.25
#: version of the edit measure: cached edit figures of another version are computed again
EDIT_MEASURE = 2


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


def edited_ceiling(run_dir: Path, program: str, truth, gcs: list, edited: list,
                   resolution: int) -> dict:
    """The edited shape's ceiling: the truth moved by the edit (`edited_truth`), its exact SDF
    meshed at the fit's grid and scored against itself at the edited GCs (what the grid allows
    on the edited shape), cached beside the run as edit_<program>_ceiling.json."""
    from bench._seams import exact_sdf_mesh
    from ngc_gen.eval import junction_metrics

    cached = run_dir / f"edit_{program}_ceiling.json"
    if _current(cached):
        return json.loads(cached.read_text())
    moved = edited_truth(truth, gcs, edited)
    mesh = exact_sdf_mesh(np.asarray(moved.vertices), np.asarray(moved.faces), resolution)
    m = junction_metrics(mesh, moved, edited)
    out = {k: m[k] for k in ("junction_ratio_dist", "junction_ratio_normal", "extra_pieces")}
    out["measure"] = EDIT_MEASURE
    cached.write_text(json.dumps(out))
    return out


def edit_record(name: str, recipe: str, program: str, m: dict, ceil: dict,
                base: dict) -> dict:
    """One `edits` entry: the edited fit's junction ratios `m`, the edited ceiling's, the
    excess (fit / ceiling) and its change from the unedited fit's excess (`base`, a `shapes`
    row): an edit keeps the seams when the excess stays within 5%. `ratio_change_*`: the raw
    ratios' change, which also moves with the edited geometry's own ceiling."""
    rec = {"name": name, "recipe": recipe, "program": program,
           "junction_ratio_dist": m["junction_ratio_dist"],
           "junction_ratio_normal": m["junction_ratio_normal"],
           "ceiling_ratio_dist": ceil["junction_ratio_dist"],
           "ceiling_ratio_normal": ceil["junction_ratio_normal"],
           "extra_pieces": m["extra_pieces"]}
    for k in ("dist", "normal"):
        fit, top = rec[f"junction_ratio_{k}"], rec[f"ceiling_ratio_{k}"]
        rec[f"excess_{k}"] = fit / top if fit is not None and top else None
        was = base.get(f"excess_{k}")
        rec[f"change_{k}"] = (rec[f"excess_{k}"] / was - 1
                              if rec[f"excess_{k}"] is not None and was else None)
        rec[f"ratio_change_{k}"] = (fit / base[f"junction_ratio_{k}"] - 1
                                    if fit is not None and base[f"junction_ratio_{k}"] else None)
    return rec


def edit_rows(programs: dict, runs: dict, rows: list[dict], resolution: int) -> list[dict]:
    """Per shape with a program and per recipe (`runs`: (name, recipe) -> run_dir): the
    junction ratios of the edited fit (its shape keeps the fit's union) against the edited
    truth, beside the edited truth's own ceiling (`edited_ceiling`, once per shape, beside the
    `before` run), and the change of the excess from the same fit's unedited one (`rows`;
    `edit_record`)."""
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
            if _current(cached):
                out.append(json.loads(cached.read_text()))
                continue
            truth, gcs = truth_and_gcs(run_dir, name)
            edited = load_shapes(run_dir / "checkpoints" / "last.ckpt")[name].edited(prog)
            ceil = edited_ceiling(runs.get((name, "before"), run_dir), program, truth, gcs,
                                  edited.gcs, resolution)
            mesh = edited.mesh(resolution).mesh
            m = junction_metrics(mesh, edited_truth(truth, gcs, edited.gcs), edited.gcs)
            base = next(r for r in rows if r["name"] == name and r["recipe"] == recipe)
            rec = edit_record(name, recipe, program, m, ceil, base)
            cached.write_text(json.dumps(rec))
            out.append(rec)
    return out


def _current(path: Path) -> bool:
    """Whether a cached edit figure exists and was measured by this version (`EDIT_MEASURE`)."""
    return path.exists() and json.loads(path.read_text()).get("measure") == EDIT_MEASURE


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
        meshes = [trimesh.load(d / "meshes" / f"{name}.ply", process=False)
                  for d in (before, after)]
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
