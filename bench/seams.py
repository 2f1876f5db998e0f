"""Seams benchmark: the min union on samples without outer-shell samples (`before`) and the
default recipe (`after`: the blended union, half the volume samples in the GCs' outer shells),
each scored where GCs meet against its ceiling.

    python -m bench.seams [--only ant creature_0000] [--steps 1500] [--resolution 256]
                          [--fit-workers 2] [--no-picture] [--no-timing]

Shapes (`SHAPES`): pyvista's ant and airplane with their hand-annotated GCs, two procedural
creatures with their parts, and the rest poses of four animals (deer, horse, fox, wolf) with
their rig's GCs; each fitted on its own as a user fits one asset (train.py stage=fit, one
thread, `--steps`, meshed at `--resolution`) twice: `before` with the min union
(`model.union.kind=min`, the paper's) on uniform volume samples (`prepare.shell_fraction=0`),
`after` with the default recipe. Each is scored by its own fit stage (metrics.json,
meshes/<name>.ply). The default loss does not depend on the union (`model.union.loss_shares` is
off) and both draw the same number of rows per batch, so a step costs the same; the networks
differ by their samples (`same_network`: whether the two checkpoints' weights are equal), and
step_s is each fit's own measured training time per step. The meshes are staged by bench/_seams.py; fits go through the bench's
fit cache (`FitCache("seams")`: rerun to fill in what is missing, a stopped run keeps what it
fitted).

Per shape and recipe, bench/results/seams.json `shapes` holds {name, recipe,
junction_ratio_dist, junction_ratio_normal, ceiling_ratio_dist, ceiling_ratio_normal,
excess_dist, excess_normal, extra_pieces, nc, fscore, ceiling_nc, ceiling_fscore,
step_s, train_s, steps, same_network, local_ratio_*, ceiling_local_ratio_*, excess_local_*,
net_ratio_*} (ngc_gen.eval.junctions; docs/metrics.md): the fit's error where GCs
meet over its error elsewhere, the same figures of the mesh's exact SDF meshed at the same grid
(the ceiling: what the grid allows), the fit's excess = its ratio over the ceiling's, loose
pieces, NC and F@0.01, and training seconds per step. `local_*`: the same with each junction
against the parts that meet there (`junction_ratio_*_local`); `net_ratio_*`: the fit's error
beyond the ceiling's, at junctions over elsewhere (`net_ratio`). `edits`: the shipped edit programs on the
ant and a creature (`EDITS`), each fit's junction ratios after the edit against the truth moved
by the same edit (`edited_truth`) beside that moved truth's own ceiling, and the change of the
excess (fit / ceiling) from the unedited fit's. `step_time`: the two recipes' training seconds
per step timed side by side in this run (`side_by_side`: {step_s: {before, after}, ratio,
shape, steps, warmup, repeats}). `minutes`: this
run's wall time. bench/results/seams.png: per shape, its worst junction close up (truth, before,
after). The JSON is written after each shape (`complete`: false until every shape is in).
"""
from __future__ import annotations

import argparse
import json
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bench._harness import Bench, FitCache, config_recipe, file_identity, train_subprocess

ROOT = Path(__file__).resolve().parents[1]
#: (name, GCs) of every bench shape: the GCs the shape ships with (bench/_seams.py stages them)
SHAPES = (("ant", "annotated"), ("airplane", "annotated"), ("creature_0000", "annotated"),
          ("creature_0001", "annotated"), ("deer", "rig"), ("horse", "rig"), ("fox", "rig"),
          ("wolf", "rig"))
#: recipe -> its train.py overrides: the min union (the paper's) on samples without shell
#: samples, the defaults (the blend, `prepare.shell_fraction`)
FIT = {"before": ["model.union.kind=min", "prepare.shell_fraction=0"], "after": []}
#: recipe -> its prepared samples' folder under .cache/prepared (the recipes draw different ones)
PREPARED = {"before": "seams", "after": "seams_after"}
RECIPES = tuple(FIT)
#: shipped edit programs measured on the fitted shapes (ngc_gen/conf/edit)
EDITS = {"ant": "posed_ant_leg", "creature_0000": "bent_tail"}
CLOSEUP = 0.08   # radius of a close-up around the worst junction (normalised units)


def staged(only: list[str] | None) -> list[tuple[str, str, Path]]:
    """(name, gcs, folder) of the bench shapes (in `--only`, if given), staged once."""
    from bench import _seams

    want = {(n, g) for n, g in SHAPES if not only or n in only}
    return [(n, g, f) for n, g, f in _seams.staged() if (n, g) in want]


def overrides(folder: Path, steps: int, resolution: int, recipe: str = "before") -> list[str]:
    return ["stage=fit", "data=folder", f"data.path={folder}", f"trainer.max_steps={steps}",
            f"extract.resolution={resolution}", "trainer.enable_progress_bar=false",
            "logger=csv", *FIT[recipe],
            f"prepare.cache_dir={ROOT}/.cache/prepared/{PREPARED[recipe]}/{folder.name}"]


def prepare(folder: Path, steps: int, resolution: int) -> None:
    """The shape's training samples of each recipe, once before its fits."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.prepare_data import prepare_dataset

    for recipe in RECIPES:
        prepare_dataset(compose_config(overrides=overrides(folder, steps, resolution, recipe)),
                        verbose=False)


def fit_one(cache: FitCache, name: str, folder: Path, recipe: str, steps: int,
            resolution: int, refit: bool = False):
    """One shape, one recipe: a cached train.py run in its own process (one thread), scored by
    its fit stage with the recipe's union."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.data.prepare import CACHE_VERSION

    over = overrides(folder, steps, resolution, recipe)

    def fit(run_dir: Path) -> dict:
        wall = train_subprocess(over, run_dir, f"the fit of {name} ({recipe})")
        return {"wall_s": wall, "label": f"{name}/{recipe}"}

    f = cache.get({"stage": "seams_fit", "config": config_recipe(compose_config(overrides=over)),
                   "data": file_identity([folder]), "prepared": CACHE_VERSION}, fit, refit=refit)
    print(f"{name} ({recipe}) {'cached' if f.reused else 'fitted'}: {f.run_dir}", flush=True)
    return f


def same_network(a: Path, b: Path) -> bool:
    """Whether two fits' checkpoints hold equal weights (decoder and codes)."""
    import torch

    sa, sb = (torch.load(d / "checkpoints" / "last.ckpt", map_location="cpu",
                         weights_only=True)["state_dict"] for d in (a, b))
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


LOCAL = ("junction_ratio_dist_local", "junction_ratio_normal_local")


def fit_figures(run_dir: Path, name: str) -> dict:
    """The fit's scores (metrics.json), with the junction figures it lacks when an older
    version scored it (the local ratios) computed from its mesh and cached as junctions.json."""
    s = json.loads((run_dir / "metrics.json").read_text())["shapes"][name]
    if all(k in s for k in LOCAL):
        return s
    path = run_dir / "junctions.json"
    if not path.exists():
        import trimesh

        from bench._seams import truth_and_gcs
        from ngc_gen.eval import junction_metrics

        truth, gcs = truth_and_gcs(run_dir, name)
        mesh = trimesh.load(run_dir / "meshes" / f"{name}.ply", process=False)
        path.write_text(json.dumps(junction_metrics(mesh, truth, gcs)))
    return {**s, **json.loads(path.read_text())}


def row(name: str, recipe: str, run_dir: Path, ceil: dict) -> dict:
    """seams.json `shapes` entry of one fit run (its metrics.json) beside its ceiling."""
    m = json.loads((run_dir / "metrics.json").read_text())
    s = fit_figures(run_dir, name)
    out = {"name": name, "recipe": recipe,
           "junction_ratio_dist": s["junction_ratio_dist"],
           "junction_ratio_normal": s["junction_ratio_normal"],
           "ceiling_ratio_dist": ceil["junction_ratio_dist"],
           "ceiling_ratio_normal": ceil["junction_ratio_normal"],
           "extra_pieces": s["extra_pieces"], "nc": s["normal_consistency"],
           "fscore": s["fscore"], "ceiling_nc": ceil["nc"], "ceiling_fscore": ceil["fscore"],
           "train_s": m["train_s"], "steps": m["steps"],
           "step_s": m["train_s"] / max(1, m["steps"] - m.get("start_step", 0))}
    for k in ("dist", "normal"):
        fit, top = out[f"junction_ratio_{k}"], out[f"ceiling_ratio_{k}"]
        out[f"excess_{k}"] = fit / top if fit is not None and top else None
        out[f"local_ratio_{k}"] = s.get(f"junction_ratio_{k}_local")
        out[f"ceiling_local_ratio_{k}"] = ceil.get(f"junction_ratio_{k}_local")
        fit, top = out[f"local_ratio_{k}"], out[f"ceiling_local_ratio_{k}"]
        out[f"excess_local_{k}"] = fit / top if fit is not None and top else None
        out[f"net_ratio_{k}"] = net_ratio(s, ceil, "dist" if k == "dist" else "normal_deg")
    return out


def net_ratio(fit: dict, ceil: dict, what: str) -> float | None:
    """The fit's error beyond the grid's at junctions over the same elsewhere: (fit - ceiling)
    of the mean junction error over (fit - ceiling) of the mean elsewhere error."""
    try:
        den = fit[f"elsewhere_{what}"] - ceil[f"elsewhere_{what}"]
        return (fit[f"junction_{what}"] - ceil[f"junction_{what}"]) / den if den > 0 else None
    except (KeyError, TypeError):
        return None


def meets_targets(r: dict) -> bool:
    """The issue's bar for one fit: excess <= 1.15 on both ratios, no extra piece, NC and F at
    least min(0.95, the ceiling's own - 0.01)."""
    ok = all(r[f"excess_{k}"] is not None and r[f"excess_{k}"] <= 1.15
             for k in ("dist", "normal"))
    return (ok and r["extra_pieces"] == 0
            and r["nc"] >= min(0.95, r["ceiling_nc"] - 0.01)
            and r["fscore"] >= min(0.95, r["ceiling_fscore"] - 0.01))


def table(res: dict) -> str:
    """bench/README.md's block: one row per shape and union, then the edited shapes."""
    lines = rows_table(res["shapes"]) + ([""] if res.get("edits") else [])
    for e in res.get("edits", []):
        lines.append(edit_line(e))
    done = "" if res.get("complete", True) else " (partial: not every shape is in)"
    ratio, timed = step_ratio(res["shapes"]), res.get("step_time")
    steps = "" if ratio is None else f"; the fits' own time per step, after / before: " \
        f"{ratio:.3f} (fits from the cache ran at other loads)"
    if timed:
        steps += (f"; side by side in this run ({timed['shape']}, {timed['repeats']} x "
                  f"{timed['steps']} steps of each, alternating): after / before "
                  f"{timed['ratio']:.3f} ({1e3 * timed['step_s']['after']:.1f} / "
                  f"{1e3 * timed['step_s']['before']:.1f} ms)")
    return "\n".join(lines) + f"\n\n{res['steps']} steps, {res['resolution']}^3, " \
        f"{res['minutes']:.1f} min{done}{steps}"


#: the side-by-side timing: shape, timed steps per run, warm-up steps left out, runs per recipe
TIMING = ("creature_0000", 120, 20, 2)


def side_by_side(folder: Path, steps: int, warmup: int, repeats: int) -> dict:
    """Training seconds per step of each recipe on one shape, measured in this run with the
    recipes alternating (before, after, before, after) so a change of load hits both alike;
    the fits' own step_s come from whichever run fitted them (the cache) and cannot be
    compared. A StepTimer callback (bench/_step_timer.py) records every step's end."""
    import tempfile

    per_step = {r: [] for r in RECIPES}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeats):
            for recipe in RECIPES:
                out = Path(tmp) / f"{recipe}_{i}"
                out.mkdir()
                train_subprocess([*overrides(folder, steps, 16, recipe),
                                  "+callbacks.timer._target_=bench._step_timer.StepTimer",
                                  f"+callbacks.timer.out_dir={out}"], out,
                                 f"the timing run of {recipe}")
                per_step[recipe].append(json.loads((out / "rank0.json").read_text())["times"])
    return step_seconds(per_step, warmup) | {"shape": folder.name, "steps": steps,
                                             "warmup": warmup, "repeats": repeats}


def step_seconds(step_ends: dict, warmup: int) -> dict:
    """{step_s: {recipe: seconds per step over its runs, from the end of step `warmup` to the
    last (epoch ends, checkpoints and data loading included, as in a fit)}, ratio: after /
    before (target: <= 1.15)}. step_ends: recipe -> per run, the perf_counter at each step's end."""
    per = {r: sum(e[-1] - e[warmup] for e in runs) / sum(len(e) - 1 - warmup for e in runs)
           for r, runs in step_ends.items()}
    return {"step_s": per, "ratio": per["after"] / per["before"]}


def step_ratio(rows: list[dict]) -> float | None:
    """The after fits' training seconds per step over the before fits', summed over the shapes
    both recipes fitted (target: <= 1.15)."""
    by = {(r["name"], r["recipe"]): r["step_s"] for r in rows}
    names = [n for n, rec in by if rec == "after" and (n, "before") in by]
    den = sum(by[n, "before"] for n in names)
    return sum(by[n, "after"] for n in names) / den if den else None


def edit_line(e: dict) -> str:
    """One edited shape: its junction ratios, the edited ceiling's, the excess and its change
    from the unedited fit's (target: within 5%)."""
    def pct(x):
        return "-" if x is None else f"{x:+.1%}"

    if "excess_dist" not in e:   # an older result: the raw ratios' change only
        return (f"- edit `{e['program']}` on {e['name']} ({e['recipe']}): junction "
                f"{e['junction_ratio_dist']:.2f} / {e['junction_ratio_normal']:.2f}, "
                f"change {pct(e['change_dist'])} / {pct(e['change_normal'])}")
    return (f"- edit `{e['program']}` on {e['name']} ({e['recipe']}): junction "
            f"{e['junction_ratio_dist']:.2f} / {e['junction_ratio_normal']:.2f}, edited "
            f"ceiling {e['ceiling_ratio_dist']:.2f} / {e['ceiling_ratio_normal']:.2f}, excess "
            f"{e['excess_dist']:.2f} / {e['excess_normal']:.2f}, change of the excess "
            f"{pct(e['change_dist'])} / {pct(e['change_normal'])} (raw ratios "
            f"{pct(e['ratio_change_dist'])} / {pct(e['ratio_change_normal'])}), "
            f"{e['extra_pieces']} extra")


def headline(res: dict) -> str:
    after = [r for r in res["shapes"] if r["recipe"] == "after"]
    met = sum(meets_targets(r) for r in after)
    worst = max((max(r["excess_dist"] or 0, r["excess_normal"] or 0) for r in after), default=0)
    return (f"blended union: {met}/{len(after)} shapes meet the seam targets; worst excess over "
            f"the ceiling {worst:.2f}")


def rows_table(rows: list[dict]) -> list[str]:
    def f(x, p=2):
        return "-" if x is None else f"{x:.{p}f}"

    out = ["| shape | recipe | junction d / n | ceiling d / n | excess d / n | local excess d / n "
           "| net d / n | extra | NC | F | ms/step | met |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['name']} | {r['recipe']} | {f(r['junction_ratio_dist'])} / "
                   f"{f(r['junction_ratio_normal'])} | {f(r['ceiling_ratio_dist'])} / "
                   f"{f(r['ceiling_ratio_normal'])} | {f(r['excess_dist'])} / "
                   f"{f(r['excess_normal'])} | {f(r.get('excess_local_dist'))} / "
                   f"{f(r.get('excess_local_normal'))} | {f(r.get('net_ratio_dist'))} / "
                   f"{f(r.get('net_ratio_normal'))} | {r['extra_pieces']} | {f(r['nc'], 3)} | "
                   f"{f(r['fscore'], 3)} | {1e3 * r['step_s']:.1f} | "
                   f"{'yes' if meets_targets(r) else 'no'} |")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, help="only these shapes (names)")
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--fit-workers", type=int, default=2, help="fits side by side")
    ap.add_argument("--no-picture", action="store_true")
    ap.add_argument("--no-timing", action="store_true",
                    help="skip the side-by-side step timing of the two recipes")
    ap.add_argument("--refit", action="store_true",
                    help="fit again (the cache keys the config, not the code)")
    args = ap.parse_args()
    names = [n for n, _ in SHAPES]
    bad = [n for n in args.only or [] if n not in names]
    if bad:
        raise SystemExit(f"--only: {bad} not among the bench shapes {names}")
    bench = Bench("seams")
    t0 = time.perf_counter()
    from bench import _seams_close as close

    shapes = staged(args.only)
    for _, _, folder in shapes:
        prepare(folder, args.steps, args.resolution)
    cache = FitCache("seams")
    rows, edits, runs, lock = kept(bench.path, {n for n, _, _ in shapes}), [], {}, \
        threading.Lock()
    edits = [e for e in _old(bench.path).get("edits", []) if e["name"] in runs_of(rows)]
    timed = {"step_time": _old(bench.path)["step_time"]} if "step_time" in _old(bench.path) \
        else {}

    def one(shape) -> None:   # fit, then score at once: a stopped run keeps whole shapes
        name, _, folder = shape
        done = {(name, r): fit_one(cache, name, folder, r, args.steps, args.resolution,
                                   args.refit).run_dir for r in RECIPES}
        ceil = _ceiling(done[name, "before"], name, args.resolution)
        same = same_network(done[name, "before"], done[name, "after"])
        mine = [{**row(name, r, done[name, r], ceil), "same_network": same} for r in RECIPES]
        edited = close.edit_rows({name: EDITS[name]} if name in EDITS else {}, done, mine,
                                 args.resolution)
        with lock:
            runs.update(done)
            rows.extend(mine)
            edits.extend(edited)
            write(complete=False)

    def write(complete: bool) -> dict:
        order = {n: i for i, (n, _) in enumerate(SHAPES)}
        rows.sort(key=lambda r: (order[r["name"]], RECIPES.index(r["recipe"])))
        res = {"shapes": rows, "edits": edits, "steps": args.steps,
               "resolution": args.resolution,
               "complete": complete and {n for n, _ in SHAPES} <= runs_of(rows),
               "minutes": (time.perf_counter() - t0) / 60.0, **timed}
        bench.write(res)
        return res

    with ThreadPoolExecutor(max(1, args.fit_workers)) as pool:
        list(pool.map(one, shapes))
    timing = next((f for n, _, f in shapes if n == TIMING[0]), None)
    if timing is not None and not args.no_timing:
        print(f"timing the recipes side by side on {TIMING[0]} ...", flush=True)
        timed["step_time"] = side_by_side(timing, *TIMING[1:])
    res = write(complete=True)
    if not args.no_picture:
        close.picture(rows, runs, bench.path.parent / "seams.png", CLOSEUP)
    print(table(res))


def _old(path: Path) -> dict:
    return json.loads(path.read_text()) if path.exists() else {}


def kept(path: Path, names: set) -> list[dict]:
    """The rows of an earlier result for the shapes this run does not fit (`--only`)."""
    return [r for r in _old(path).get("shapes", []) if r["name"] not in names]


def runs_of(rows: list[dict]) -> set:
    return {r["name"] for r in rows}


def _ceiling(run_dir: Path, name: str, resolution: int) -> dict:
    from bench import _seams

    return _seams.ceiling(run_dir, name, resolution)


if __name__ == "__main__":
    main()
