"""Fit-quality ablation table: the screening runs of `bench/fit.py --tag` side by side.

    python -m bench.fit --tag lr1e2 --methods ngc --threads 1 --set model.lr=1e-2   # one screen
    python -m bench.fit --tag lr1e2 --methods ngc --rescore                         # new metrics
    python -m bench.fit_ablation [TAG ...]                                          # the table
    python -m bench.fit_ablation --picture baseline default   # fit_before_after.png, one camera

Reads bench/runs/fit/<tag>/fit.json (every tag, or those given; `baseline` is the default recipe)
and bench/results/fit.json's ceiling, and writes bench/results/fit_ablation.json ({ceiling, runs:
{tag: {cd, hd, nc, fscore, fragments, train_s, load, overrides, steps, resolution, per_shape,
machine}}, machine}: each run's own machine record where it has one, and this table's;
bench/_harness.py); its table is bench/README.md's (bench/report.py). Every run is the NGC multi-GC
fit of the 7 bench shapes at equal steps x batch, so equal wall time on an idle machine unless an
override adds network cost (the table says which); train_s is as measured, with the load.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bench._harness import Bench

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "bench/runs/fit"
OUT = ROOT / "bench/results"


def collect(tags: list[str]) -> dict:
    runs = {}
    for tag in tags or sorted(p.parent.name for p in RUNS.glob("*/fit.json")):
        res = json.loads((RUNS / tag / "fit.json").read_text())
        m = res["methods"]["ngc"]
        per = res["per_shape"]["ngc"]
        runs[tag] = {k: m.get(k) for k in ("cd", "hd", "nc", "fscore", "fragments", "train_s",
                                            "load", "overrides", "steps")}
        runs[tag]["resolution"] = res.get("resolution")
        runs[tag]["surface_metrics"] = all("fscore_samples" in p for p in per.values())
        runs[tag]["per_shape"] = {s: {"cd": p["cd"], "nc": p["normal_consistency"],
                                      "fscore": p["fscore"], "fragments": p["fragments"]}
                                  for s, p in per.items()}
        runs[tag]["machine"] = res.get("machine")   # when and where that screening ran
    return runs


def run_meshes(tag: str) -> Path:
    """The meshes of a screening tag, or of the bench's own NGC run (`default`:
    bench/runs/fit/ngc, what bench/results/fit.json reports)."""
    d = RUNS / "ngc" / "meshes" if tag == "default" else RUNS / tag / "ngc" / "meshes"
    if not d.is_dir():
        raise SystemExit(f"no meshes in {d}: run `python -m bench.fit --tag {tag} ...` first")
    return d


def picture(before: str, after: str, shapes: list[str], path: Path) -> None:
    """Per shape: ground truth, `before`'s and `after`'s meshes under one camera and one scale
    (render_grid frame="row"), so bumps and stripes compare at the same size."""
    import trimesh

    from ngc_gen.data.prepare import load_prepared
    from ngc_gen.viz import render_grid

    rows = []
    for shape in shapes:
        prep = load_prepared(ROOT / ".cache/prepared/fitbench" / f"{shape}.npz")
        rows.append([trimesh.Trimesh(prep.mesh_vertices, prep.mesh_faces, process=False)] +
                    [trimesh.load(run_meshes(t) / f"{shape}.ply", process=False)
                     for t in (before, after)])
    render_grid(rows, path, labels=shapes, col_titles=["ground truth", before, after],
                cell=(360, 300), frame="row")
    print(f"saved {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tags", nargs="*")
    ap.add_argument("--picture", nargs=2, metavar=("BEFORE", "AFTER"),
                    help="two runs' meshes side by side: bench/results/fit_before_after.png")
    ap.add_argument("--shapes", nargs="+", default=["ant", "creature_0000", "creature_0005"])
    args = ap.parse_args()
    if args.picture:
        return picture(*args.picture, args.shapes, OUT / "fit_before_after.png")
    bench = Bench("fit_ablation")
    res = {"runs": collect(args.tags)}
    if not res["runs"]:   # a fresh checkout: keep the committed table rather than empty it
        print(f"no screening runs in {RUNS}/*/fit.json (`python -m bench.fit --tag TAG ...` "
              f"makes one): {bench.path} left as it is")
        return 0
    fit = OUT / "fit.json"
    if fit.exists():
        res["ceiling"] = json.loads(fit.read_text()).get("ceiling")
    print(table(res))
    print(f"saved {bench.write(res)}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(res: dict) -> str:
    lines = ["| run | overrides | grid | CD x1e-4 | NC | F@0.01 | fragments | HD | train_s "
             "| load |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    c = res.get("ceiling")
    if c:
        m = c["mean"]
        lines.append(f"| ceiling (exact SDF) | | {c['resolution']} | {m['cd'] * 1e4:.2f} | "
                     f"{m['nc']:.3f} | {m['fscore']:.3f} | {m['fragments']} | {m['hd']:.4f} | "
                     "| |")
    order = sorted(res["runs"].items(),
                   key=lambda kv: (not kv[0].startswith("baseline"), -kv[1]["nc"]))
    for tag, r in order:
        load = r.get("load") or []
        load_s = f"{load[0]:.1f}-{load[3]:.1f}" if len(load) >= 4 else ""
        mark = "" if r.get("surface_metrics") else " \u2020"
        lines.append(f"| {tag} | {' '.join(r.get('overrides') or [])} | {r['resolution']} | "
                     f"{r['cd'] * 1e4:.2f} | "
                     f"{r['nc']:.3f}{mark} | {r['fscore']:.3f}{mark} | {r['fragments']} | "
                     f"{r['hd']:.4f} | "
                     f"{r['train_s']:.0f} | {load_s} |")
    return "\n".join(lines)


def headline(r):
    runs = r["runs"]
    best = max(runs, key=lambda k: runs[k]["fscore"])
    b = runs["baseline"]
    return (f"{len(runs)} recipes screened; best `{best}` against `baseline`: F {b['fscore']:.3f} "
            f"-> {runs[best]['fscore']:.3f}, fragments {b['fragments']} -> "
            f"{runs[best]['fragments']}")


if __name__ == "__main__":
    sys.exit(main())
