"""bench/README.md's tables, generated from bench/results/<name>.json: one source for every figure.

    python bench/report.py            # rewrite the tables in bench/README.md (make bench-report)
    python bench/report.py --check    # exit 1 and show the difference if a table is stale

The project README's "Results at a glance" is the `glance` block: one headline per bench
(`GLANCE[name](result)`), from the same results.

Each bench's section of bench/README.md holds one block between `<!-- table:<name> -->` and
`<!-- /table:<name> -->`; everything between the markers is replaced by `block(name, result)`:
the bench's tables (`TABLES[name](result)`) and one line from its machine record
(bench/_harness.py). The prose around the blocks is written by hand and holds no figures.
The benches print their own table with `table(name, result)` when they finish.
tests/bench/test_bench_report.py fails when bench/README.md differs from what this writes.
Standard library only.
"""
from __future__ import annotations

import argparse
import difflib
import json
import re
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench/results"
README = ROOT / "bench/README.md"
PAGES = (README, ROOT / "README.md")   # the project README holds the `glance` block
BLOCK = re.compile(r"(<!-- table:(?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- /table:(?P=name) -->)",
                   re.S)


# ---- small formats ----------------------------------------------------------------------------
def count(n: float) -> str:
    """2.1M, 40k, 512."""
    if n >= 1e6:
        return f"{n / 1e6:.1f}M"
    if n >= 1e3:
        return f"{n / 1e3:.0f}k"
    return f"{n:.0f}"


def pct(x: float, digits: int = 2) -> str:
    return f"{100 * x:.{digits}f}%"


def rows_table(header: list[str], rows: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out


def span(values, fmt: str = ".2f") -> str:
    """min-max of values."""
    return f"{min(values):{fmt}}-{max(values):{fmt}}"


# ---- the machine line ------------------------------------------------------------------------
def machine_line(name: str, res: dict) -> str:
    """One line from the result's machine record. A record without `dirty` (None) comes from a
    result written before the harness: its commit is the one that recorded the result."""
    m = res.get("machine") or {}
    commit = (m.get("commit") or "unknown")[:7]
    if m.get("dirty") is None:
        where = f"Recorded in commit {commit}"
    else:
        where = f"Measured at commit {commit}" + (" with uncommitted changes" if m["dirty"]
                                                  else "")
    date = (m.get("date_utc") or "unknown date").replace("T", " ").replace("Z", " UTC")
    parts = []
    if m.get("cpus") is not None:
        parts.append(f"{m['cpus']} CPUs")
    threads = m.get("torch_threads")
    if threads is not None:
        parts.append(f"{threads} torch thread{'s' if threads != 1 else ''}")
    load = [f"{m[k]:.2f} {w}" for k, w in (("load_1min_before", "before"),
                                           ("load_1min_after", "after"))
            if m.get(k) is not None]
    if load:
        parts.append("1-minute load " + ", ".join(load))
    return (f"_{where}, {date}" + (f"; {', '.join(parts)}" if parts else "")
            + f" (`bench/results/{name}.json`)._")


# ---- per bench -------------------------------------------------------------------------------
def geometry(r: dict) -> str:
    names = ", ".join(r["prepare_shapes"])
    load = r.get("load_1min_at_wall_timing")
    rows = [["relative coordinates, float32, 1M points, 128-segment curve, all cores (wall)",
             f"{r['relcoords_points_per_s_wall_all_cores'] / 1e6:.2f} M points/s"
             + (f" (load {load:.1f})" if load is not None else "")],
            ["the same, one thread", f"{r['relcoords_points_per_s'] / 1e6:.2f} M points per "
                                     "CPU-second"],
            ["baseline: projection onto all 128 polyline segments, one thread",
             f"{r['polyline_points_per_s'] / 1e6:.2f} M points per CPU-second "
             f"({r['speedup_vs_polyline']:.0f}x slower)"],
            ["round-trip error `to_world(to_relative(q)) - q`, Newton on the smooth curve",
             f"{r['roundtrip_err_newton']:.1e} (float32 points: "
             f"{r['roundtrip_err_newton_float32']:.1e})"],
            ["round-trip error, plain 128-segment polyline", f"{r['roundtrip_err_polyline']:.1e}"]]
    if "closest_point_excess_max" in r:
        rows.append(["closest point: largest excess of the computed foot's distance over the "
                     f"brute force's ({count(r['closest_point_points'])} points, "
                     f"{r['closest_point_gcs']} random Bezier GCs; target <= 1e-9)",
                     f"{r['closest_point_excess_max']:.1e}"])
    rows.append([f"preparation, {count(r['prepare_n_samples'])} samples, mean over {names}",
                 f"{r['prepare_s_per_shape']:.2f} CPU-seconds per shape"])
    return "\n".join(rows_table(["measure", "value"], rows))


def up_axis(r: dict) -> str:
    groups: dict[str, list] = {}
    for m in r["meshes"]:
        if m.get("up"):
            key = "creatures" if m["name"].startswith("creature_") else m["name"]
            groups.setdefault(key, []).append(m)
    rows = []
    for key, ms in groups.items():
        label = f"{len(ms)} {key}" if key == "creatures" else key
        rows.append([f"{label} (up {ms[0]['up']})", 6 * len(ms), sum(m["right"] for m in ms),
                     sum(m["axis_only"] for m in ms), sum(m["wrong"] for m in ms)])
    t = r["totals"]
    rows.append(["**all**", t["orientations"], t["right"], t["axis_only"], t["wrong"]])
    lines = rows_table(["meshes", "orientations", "right", "right axis, wrong sign", "wrong"],
                       rows)
    free = [f"{m['name']} {m['detected']['as shipped']}" for m in r["meshes"] if not m.get("up")]
    lines += ["", f"{1e3 * r['seconds_per_mesh']:.0f} ms per mesh. Meshes with no natural up, "
                  f"as shipped: {', '.join(free)}."]
    return "\n".join(lines)


LABELS = {"ngc": "NGC, multi-GC", "ngc_1gc": "NGC, one GC", "deepsdf": "DeepSDF"}


def _gt_fragments(res: dict):
    counts = {m.get("gt_fragments") for m in res["methods"].values()} - {None}
    return counts.pop() if len(counts) == 1 else "-"


def _long_status(long: dict) -> str:
    done = "it ran its whole schedule" if long["steps"] >= long["max_steps"] else \
        f"it has not finished its schedule ({long['steps']} of {long['max_steps']} steps)"
    fall = long.get("loss_last_fifth")
    if not fall:
        return done
    a, b = fall
    return (f"{done}; its training loss fell {100 * (a - b) / a:.0f}% over the last fifth of "
            f"the steps ({a:.2e} -> {b:.2e})")


def fit(res: dict) -> str:
    lines = ["| method | CD (x1e-4) | HD | EMD | NC | F@0.01 | fragments | train time (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, label in LABELS.items():
        if name not in res["methods"]:
            continue
        m = res["methods"][name]
        lines.append(f"| {label} | {m['cd'] * 1e4:.2f} | {m['hd']:.4f} | {m['emd']:.4f} | "
                     f"{m.get('nc', float('nan')):.3f} | {m.get('fscore', float('nan')):.3f} | "
                     f"{m.get('fragments', '-')} | {m['train_s']:.0f} |")
    long = res.get("deepsdf_long")
    if long:
        for label, m in (("DeepSDF, own recipe, at NGC's time", long.get("at_ngc_time")),
                         (f"DeepSDF, own recipe, {long['steps']} steps", long)):
            if m:
                lines.append(f"| {label} | {m['cd'] * 1e4:.2f} | {m['hd']:.4f} | "
                             f"{m['emd']:.4f} | {m['nc']:.3f} | {m['fscore']:.3f} | "
                             f"{m['fragments']} | {m['train_s']:.0f} |")
    r = (res["methods"]["ngc"]["cd"] / res["methods"]["deepsdf"]["cd"]
         if {"ngc", "deepsdf"} <= set(res["methods"]) else float("nan"))
    lines.append("")
    lines.append(f"Mean over {len(res['shapes'])} shapes ({', '.join(res['shapes'])}); "
                 f"{res['steps']} steps of {res['batch_size']} samples each, small presets "
                 f"(~47k parameters each), meshes at {res['resolution']}^3. NGC CD / DeepSDF CD "
                 f"= {r:.2f} (paper: 0.53). Fragments of the ground truth: "
                 f"{_gt_fragments(res)}.")
    if "ceiling" in res:
        c = res["ceiling"]["mean"]
        lines.append("")
        lines.append(f"Ceiling at {res['ceiling']['resolution']}^3 (each shape's exact signed "
                     f"distance meshed and scored the same way): CD {c['cd'] * 1e4:.2f}e-4, NC "
                     f"{c['nc']:.3f}, F@0.01 {c['fscore']:.3f}, fragments {c['fragments']}.")
    if long and "ngc" in res["methods"]:
        lines.append("")
        lines.append(f"DeepSDF, own recipe: lr halved every quarter of {long['max_steps']} "
                     f"steps; stopped at step {long['steps']}, meshes at "
                     f"{long.get('resolution', res['resolution'])}^3 (coarse-to-fine). NGC CD / "
                     f"its CD = {res['methods']['ngc']['cd'] / long['cd']:.2f} (paper: 0.53); "
                     f"{_long_status(long)}.")
    p = res.get("prefilter")
    if p:
        lines.append("")
        lines.append(f"GC prefilter on the fitted {p['shape']} at {p['resolution']}^3: grids "
                     f"identical {p['identical_grid']}, meshes identical {p['identical_mesh']}; "
                     f"{p['eval_ratio']:.0f}x fewer network evaluations than dense.")
    if res.get("junctions"):
        lines += ["", *fit_junctions(res["junctions"],
                                     res.get("ceiling", {}).get("per_shape", {}))]
    return "\n".join(lines)


JUNCTION_TARGET = 1.3   # junction error / elsewhere error, distance and normal (issue 32)


def fit_junctions(rows: list[dict], ceiling: dict | None = None) -> list[str]:
    """fit.json's `junctions`: per shape and run, the fit's error where GCs meet / elsewhere
    (distance, normal angle), extra pieces, NC and F@0.01, beside the ceiling's junction
    ratios (the shape's exact SDF on the same grid, where measured); then how many meet the
    targets."""
    def r(x):
        return "-" if x is None or x != x else f"{x:.2f}"

    own = {(j["name"], j["gcs"]): j["ceiling"] for j in rows if j.get("ceiling")}

    def ceil(j):   # the mesh's own ceiling (bench/_seams.py), else the fitbench's by name
        c = own.get((j["name"], j["gcs"])) or (ceiling or {}).get(j["name"], {})
        if "junction_ratio_dist" not in c:
            return "-"
        return f"{r(c['junction_ratio_dist'])} / {r(c['junction_ratio_normal'])}"

    out = rows_table(["shape", "GCs", "recipe", "junction / elsewhere: distance", "normal",
                      "extra pieces", "NC", "F@0.01", "ceiling: distance / normal"],
                     [[j["name"], j["gcs"], j["recipe"], r(j["junction_ratio_dist"]),
                       r(j["junction_ratio_normal"]), j["extra_pieces"], f"{j['nc']:.3f}",
                       f"{j['fscore']:.3f}", ceil(j)] for j in rows])
    for recipe in dict.fromkeys(j["recipe"] for j in rows):
        mine = [j for j in rows if j["recipe"] == recipe]
        ratios = [max(j["junction_ratio_dist"], j["junction_ratio_normal"]) for j in mine
                  if j["junction_ratio_dist"] is not None]   # None: no junction
        met = sum(x <= JUNCTION_TARGET for x in ratios)
        capped = [j for j in mine if own.get((j["name"], j["gcs"]))
                  and j["junction_ratio_dist"] is not None
                  and own[(j["name"], j["gcs"])]["junction_ratio_dist"] is not None]
        within = sum(j["junction_ratio_dist"] <= own[(j["name"], j["gcs"])]["junction_ratio_dist"]
                     and j["junction_ratio_normal"]
                     <= own[(j["name"], j["gcs"])]["junction_ratio_normal"] for j in capped)
        out.append("")
        out.append(f"{recipe}: junction / elsewhere <= {JUNCTION_TARGET} (distance and normal) "
                   f"on {met} of {len(ratios)} meshes"
                   + (f", worst {max(ratios):.2f}" if ratios else "")
                   + (f"; at or below its mesh's ceiling on {within} of {len(capped)}"
                      if capped else "")
                   + f"; {sum(j['extra_pieces'] for j in mine)} extra pieces; NC >= 0.95 on "
                   f"{sum(j['nc'] >= 0.95 for j in mine)}, F >= 0.95 on "
                   f"{sum(j['fscore'] >= 0.95 for j in mine)} of {len(mine)}.")
    return out


def fit_ablation(res: dict) -> str:
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


def extract(r: dict) -> str:
    rows = []
    for c in r["cases"]:
        dense = "-" if c["dense_s"] is None else \
            f"{c['dense_s']:.0f}*" if c["dense_s_extrapolated"] else f"{c['dense_s']:.1f}"
        cd = "0 (identical)" if c["identical_mesh"] else f"{c['cd_sparse_vs_prefiltered']:.1e}"
        edit = (f"{c['incremental_s']:.2f} ({c['full_after_edit_s']:.2f})"
                if "incremental_s" in c else "-")
        rows.append([f"{c['name']} ({c['n_gcs']})", c["resolution"], count(c["dense_evals"]),
                     count(c["prefiltered_evals"]),
                     f"{count(c['sparse_evals'])} (1/{1 / c['sparse_over_dense_evals']:.0f})",
                     dense, f"{c['prefiltered_s']:.2f}",
                     f"{c['sparse_s']:.2f} ({c['sparse_cpu_s']:.2f})", cd, edit])
    lines = rows_table(["shape (GCs)", "R", "dense evals", "prefiltered evals", "sparse evals",
                        "dense s", "prefiltered s", "sparse s (CPU s)",
                        "CD sparse vs prefiltered", "edit of one GC s (full s)"], rows)
    d, t = r["decoder"], r["targets"]
    met = lambda v: "met" if v else "not met"  # noqa: E731
    at = t["at_resolution"]
    lines += ["", f"* = extrapolated from the same shape's measured time per evaluation. "
                  f"Decoder in the same run: {d['rows_per_s_wall'] / 1e3:.0f}k rows/s wall, "
                  f"{d['rows_per_cpu_s_1_thread'] / 1e3:.0f}k rows per CPU second on one thread. "
                  f"Targets at {at}: sparse evaluations <= 1/30 of dense "
                  f"{met(all(t['sparse_evals_le_dense_over_30'].values()))}; CD < 1e-6 "
                  f"{met(all(t['cd_lt_1e-6'].values()))}; creature sparse wall time <= 1 s "
                  f"{met(t['creature_sparse_s_le_1'])}."]
    return "\n".join(lines)


def sparse_settings(r: dict) -> str:
    variants = r["settings"]["variants"]
    varying = [k for k in next(iter(variants.values()))
               if len({json.dumps(v[k]) for v in variants.values()}) > 1]
    base = next(iter(variants))
    rows = []
    for label, s in r["summary"].items():
        t = r["timing"].get(label)
        time_s = (f"{t['median_s']:.2f} ({s['median_time_over_first']:.2f}x)" if t else "-")
        ident = f"{s['identical']} of {s['cases']}" + (
            f" (largest CD {s['cd_max']:.1e})" if s["identical"] < s["cases"] else "")
        rows.append([f"`{label}`: " + ", ".join(f"{k}={variants[label][k]}" for k in varying),
                     ident, f"{s['evals_over_first_min']:.2f}-{s['evals_over_first_max']:.2f}",
                     time_s])
    t0 = next(iter(r["timing"].values()), None)
    timed = f"{t0['shape']} at {t0['resolution']}, median of {len(t0['runs_s'])}" if t0 else "-"
    fits = sorted({c["fit"] for c in r["cases"]})
    lines = rows_table(["settings", "meshes identical to prefiltered",
                        f"evaluations vs `{base}`", f"time (s), {timed}"], rows)
    lines += ["", f"{len(r['cases'])} meshes: {len({(c['fit'], c['shape']) for c in r['cases']})}"
                  f" fitted shapes of {len(fits)} fits ({', '.join(fits)}) at "
                  f"{', '.join(map(str, r['settings']['resolutions']))}."]
    return "\n".join(lines)


def deform(res: dict) -> str:
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


def generate(res: dict) -> str:
    rows = [("generated", "generated (EDM, 18 Heun steps)"),
            ("train_recon", "training latents, decoded (decoder ceiling)"),
            ("train_set", "training meshes (ceiling)"),
            ("train_decoded", "training latents decoded (the shape-latent model's ceiling)"),
            ("noise", "noise latents N(mean, std), no diffusion (floor)")]
    lines = ["| shapes vs held-out | MMD-CD (x1e-3) | COV-CD (%) | 1-NNA-CD (%) | sets |",
             "|---|---|---|---|---|"]
    for key, label in rows:
        if key in res:
            m, per = res[key], res["per_set"][key]
            rng = lambda k, f: (f" ({f * min(p[k] for p in per):.0f}-"  # noqa: E731
                                f"{f * max(p[k] for p in per):.0f})" if len(per) > 1 else "")
            lines.append(f"| {label} | {1e3 * m['mmd_cd']:.3f} | {100 * m['cov_cd']:.1f}"
                         f"{rng('cov_cd', 100)} | {100 * m['nna_cd']:.1f}{rng('nna_cd', 100)} | "
                         f"{len(per)} |")
    t = res["timing"]
    lines += ["", f"{res['n_reference']} held-out creatures as the reference, {res['n_train']} "
                  f"training creatures; shape latents {res['shape_latent_steps']} steps, "
                  f"diffusion {res['diffusion_steps']} steps; sampling per shape: latent "
                  f"{1e3 * t['latent_s_per_shape']:.0f} ms, mesh at {res['resolution']}^3 "
                  f"{t['mesh_s_per_shape']:.2f} s ({res.get('threads', 1)} torch threads). "
                  f"Targets: 1-NNA <= 65%, COV >= 50%."]
    return "\n".join(lines)


def editor(r: dict) -> str:
    s = r["settings"]
    rows = [[c["shape"], c["interaction"], f"{c['preview_s']:.2f}",
             f"{c['preview_s'] / c['extract_preview_s']:.2f}", f"{c['refine_s']:.2f}",
             c["n_faces"]] for c in r["cases"]]
    lines = rows_table(["shape", "interaction", f"preview {s['preview_resolution']}^3 (s)",
                        "x bare extraction", f"refined {s['refine_resolution']}^3 (s)", "faces"],
                       rows)
    ok = sum(c["preview_s"] <= 0.3 for c in r["cases"])
    lines += ["", f"Medians of {s['repeats']}; {ok} of {len(r['cases'])} previews within the "
                  f"0.3 s target."]
    if r.get("browser"):
        def sec(x):
            return "-" if x is None else f"{x:.2f}"

        target = s.get("browser_target_s", 0.5)
        lines += ["", "In the browser (headless Chromium; input event -> mesh drawn):", ""]
        lines += rows_table(
            ["shape", "typed into", "preview's status line (s)", "preview drawn (s)",
             "server preview extraction (s)", "refined drawn (s)",
             "server refine extraction (s)"],
            [[c["shape"], c["interaction"], sec(c.get("preview_status_s")), sec(c["preview_s"]),
              sec(c["server_preview_s"]), sec(c["refine_s"]), sec(c["server_refine_s"])]
             for c in r["browser"]])
        ok = sum(c["preview_s"] is not None and c["preview_s"] <= target for c in r["browser"])
        lines += ["", f"{ok} of {len(r['browser'])} previews drawn within the {target:g} s "
                      f"target (refined: after the {s['refine_delay_s']:g} s idle delay)."]
        first = [c["preview_s"] for c in r.get("browser_first_edits") or []
                 if c["preview_s"] is not None]
        if first:
            lines += ["", "The first edits after the page opens, before these (the page compiles "
                          "what it draws the first time): previews drawn in "
                          + ", ".join(f"{x:.2f}" for x in first) + " s."]
    return "\n".join(lines)


def condition(r: dict) -> str:
    e3 = lambda x: f"{1e3 * x:.2f}"  # noqa: E731
    lines = rows_table(
        [f"strength {r['strength']:g}, project_steps {r['project_steps']}, "
         f"{r['n_conditions']} conditions x {r['samples_per_condition']} samples", "value"],
        [["decoded GC error before replace (rms, std units)",
          f"{r['gc_err']:.3f} (max {r['gc_err_max']:.3f}; unconditional "
          f"{r['gc_err_unconditional']:.3f}; best any latent reaches: "
          f"{r['gc_err_decoder_floor']:.3f})"],
         ["Chamfer to the creature the GCs came from (x1e-3)", e3(r["cd_conditional"])],
         ["unconditional samples, same noise (floor)", e3(r["cd_unconditional"])],
         ["the creature's own latent refitted, decoders frozen, GCs replaced (ceiling)",
          e3(r["cd_refit"])],
         ["diversity: mean pairwise Chamfer of one condition's samples (x1e-3)",
          f"{e3(r['diversity'])} (unconditional {e3(r['diversity_unconditional'])})"],
         ["latent sampling per sample", f"{r['s_per_sample']:.2f} s guided, "
                                        f"{r['s_per_sample_unconditional']:.2f} s plain"],
         ["GC vectors of the held-out creatures outside the training shapes' affine hull (rms, "
          "std units)", f"{r['gc_affine_hull_residual']:.2f}"]])
    sweep = r.get("sweep")
    if sweep:
        strengths = sorted({row["strength"] for row in sweep})
        at = {(row["strength"], row["project_steps"]): row for row in sweep}
        projects = sorted({row["project_steps"] for row in sweep})
        body = []
        for p in projects:
            suffix = "" if p == 0 else f", `project_steps={p}`"
            for kind, label in (("full", "all GCs given"), ("legs", "legs given")):
                body.append([f"GC error, {label}{suffix}"] + [
                    f"{at[s, p][kind]['gc_err']:.3f}" if (s, p) in at else "" for s in strengths])
            body.append([f"legs given{suffix}: spread of the legs / other GCs"] + [
                f"{at[s, p]['legs']['spread_legs']:.2f} / {at[s, p]['legs']['spread_others']:.2f}"
                if (s, p) in at else "" for s in strengths])
        lines += [""] + rows_table(["strength"] + [f"{s:g}" for s in strengths], body)
    return "\n".join(lines)


def reconstruct(r: dict) -> str:
    rows = []
    for key, label in (("ratio", "latent, then its codes refined (the default)"),
                       ("ratio_latent_only", "latent alone"),
                       ("ratio_decoded_gcs", "latent alone, meshed with the GCs it decodes to")):
        if key in r:
            per = list(r[key]["per_shape"].values())
            rows.append([label, f"{r[key]['mean']:.2f}x ({span(per)}x)"])
    lines = rows_table(["into the generation recipe's shape-latent model", "CD / direct fit's CD,"
                        " mean (range)"], rows)
    direct = list(r["direct"].values())
    s = r["settings"]
    lines += ["", f"{len(r['shapes'])} held-out creatures ({', '.join(r['shapes'])}), meshes at "
                  f"{s['resolution']}^3; direct fit {s['fit_steps']} steps, CD "
                  f"{span([1e5 * d for d in direct], '.1f')}e-5; latent "
                  f"{r.get('reconstructed_steps')} steps, codes "
                  f"{r.get('reconstructed_refine_steps')} steps; {s['seconds']:.0f} s in all."]
    return "\n".join(lines)


AUTOGC_COLUMNS = [("cd_auto", "CD auto"), ("cd_annotated", "CD hand"), ("cd_axis", "CD axis")]


def autogc(r: dict) -> str:
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


def ddp(r: dict) -> str:
    rows = [["1 process (`trainer=cpu`)", f"{1e3 * r['step_s_1proc']:.1f}",
             f"{r['samples_per_s_1proc'] / 1e3:.0f}k"],
            ["2 processes (`trainer=ddp`, gloo)", f"{1e3 * r['step_s_2proc']:.1f}",
             f"{r['samples_per_s_2proc'] / 1e3:.0f}k"],
            ["2 / 1", f"{r['step_ratio_2_to_1']:.2f}x", f"{r['speedup_samples_per_s']:.2f}x"]]
    lines = rows_table(["setting", "ms per step", "samples/s"], rows)
    lines += ["", f"{r['batch_per_process']} samples per process per step, "
                  f"{r['threads_per_process']} torch thread per process; median over "
                  f"{r['steps_timed']} steps after {r['warmup_steps']}, "
                  f"{len(r['runs_step_s']['cpu'])} runs of each, alternating."]
    return "\n".join(lines)


def _demo_result(step: str, s: dict) -> str:
    if step == "fit":
        return (f"CD {1e4 * s['cd']:.2f}e-4, HD {s['hd']:.3f}, F-score {s['fscore']:.2f}, "
                f"watertight {s['watertight']:.0%}")
    if step == "edit":
        return f"`{s['program']}` on {s['shape']}: volume {pct(s['eps_v'])}, area {pct(s['eps_a'])}"
    if step == "shape_latent":
        return f"{s['steps']} steps, SDF L1 {s['l1']:.2e}, GC MSE {s['param']:.1e}"
    if step == "diffusion":
        return (f"{s['steps']} steps, EDM loss {s['edm_loss_untrained']:.2f} -> "
                f"{s['edm_loss_ema']:.3f} (EMA)")
    if step == "sample":
        return (f"{s['n']} shapes: {1e3 * s['latent_s_per_shape']:.0f} ms per latent, "
                f"{s['mesh_s_per_shape']:.2f} s per mesh")
    return ", ".join(f"{k} {v}" for k, v in s.items() if k not in ("dir", "seconds"))


def demo(r: dict) -> str:
    m = r["measured"]
    rows = [[f"`{k}`", f"{s['seconds']:.0f}", _demo_result(k, s)] for k, s in r["steps"].items()]
    rows.append(["setup (clone's .venv, outside the steps)", f"{m['setup_s']:.0f}", ""])
    rows.append(["**`make demo`, wall**", f"**{m['make_demo_wall_s']:.0f}**",
                 f"target {m['target_s']:.0f} s: {'met' if m['within_target'] else 'not met'}"])
    return "\n".join(rows_table(["step", "seconds", "result"], rows))


def animals(r: dict) -> str:
    rows = [("generated", "generated (EDM, 18 Heun steps)"),
            ("generated_churn", "generated (EDM, stochastic: 40 steps, S_churn 40)"),
            ("train_set", "training meshes (ceiling)"),
            ("train_decoded", "training latents decoded (the shape-latent model's ceiling)"),
            ("noise", "noise latents N(mean, std), no diffusion (floor)")]
    rows = [(k, label) for k, label in rows if k in r["clips"]]
    lines = []
    for key, title in (("clips", f"{r['n_heldout_clips']} shapes of training species at held-out clips"),
                       ("species", f"{r['n_heldout_species']} shapes of held-out species")):
        lines += [f"| vs {title} | MMD-CD (x1e-3) | COV-CD (%) | 1-NNA-CD (%) |", "|---|---|---|---|"]
        lines += [f"| {label} | {1e3 * r[key][k]['mmd_cd']:.3f} | {100 * r[key][k]['cov_cd']:.1f} | "
                  f"{100 * r[key][k]['nna_cd']:.1f} |" for k, label in rows]
        lines.append("")
    rc = r["recipe"]
    interp = r["interp_max_over_mean"]
    lines += [f"{r['n_train']} training animals ({rc['frames']} frames per clip); fit of the rest "
              f"poses {rc['fit_steps']} steps, shape latents {rc['shape_latent_steps']}, diffusion "
              f"{rc['diffusion_steps']}" + (f" (batches of {rc['diffusion_batch']})"
                                            if rc.get("diffusion_batch") else "")
              + (f" on {rc['diffusion_space_dim']} principal axes of the "
              f"latents" if rc.get("diffusion_space_dim") else "")
              + (" (the others from the nearest training latent)"
                 if rc.get("diffusion_pca_complete") == "nearest" else "")
              + (f", trained on the training latents and {rc['diffusion_transferred']} pose-transferred "
                 f"ones" if rc.get("diffusion_transferred") else "")
              + (f". Generated rows: {rc['sets']} set{'s' if rc['sets'] > 1 else ''} of as many shapes as "
                 f"the reference; ceiling: {rc['train_subsets']} training subsets" if rc.get("sets") else "")
              + ". Memorisation: median Chamfer from a generated animal to its "
              f"nearest training animal {1e3 * r['nearest_train_cd_median']:.3f} x1e-3. "
              f"{rc['interp'][0]} -> {rc['interp'][1]}: largest consecutive-step Chamfer "
              + (f"{interp:.2f} x their mean" if interp is not None else "undefined (an empty mesh)")
              + f". GCs on {r['n_train'] + r['n_heldout_clips'] + r['n_heldout_species'] + 12} "
              f"posed meshes: coverage >= {r['coverage_min']:.5f}, purity mean "
              f"{100 * r['purity_mean']:.2f}%, worst {100 * r['purity_worst']:.2f}%; rest-pose fits "
              f"({rc.get('fit', 'the 12 in one run')}) F-score@0.01 >= {r['fit_fscore_min']:.3f}."]
    return "\n".join(lines)


def cli(r: dict) -> str:
    t = r["targets"]
    rows = [[f"`{case}`", f"{sec:.2f}"] for case, sec in r["reject_s"].items()]
    lines = rows_table(["bad input", "exit 2 after (s)"], rows)
    ok = sum(v <= t["reject_s"] for v in r["reject_s"].values())
    lines += ["", f"{ok} of {len(r['reject_s'])} rejections within the {t['reject_s']:g} s "
                  f"target. An edit of the ant at 128^3 (`edit.py run=<fit> edit=posed_ant_leg "
                  f"extract.resolution=128`, picture included): {r['edit_s_128']:.2f} s with "
                  f"the setup's bytecode (target {t['edit_s_128']:g} s), "
                  f"{r['edit_s_128_no_bytecode']:.2f} s without; `--help` {r['help_s']:.2f} s "
                  f"(slowest of the three); the bytecode step adds {r['setup_s_added']:.1f} s "
                  f"to `make setup`. Medians of {r['repeat']}, PYTHONDONTWRITEBYTECODE=1."]
    return "\n".join(lines)


def _spread(row: dict) -> str:
    """' (sd over n sets: MMD-CD .., 1-NNA ..)' of a generator row that has it, else ''."""
    sd = row.get("sd_over_sets")
    return (f" (sd over sets: MMD-CD {1e3 * sd['mmd_cd']:.3f}, 1-NNA {pct(sd['nna_cd'], 1)})"
            if sd else "")


def transfer(r: dict) -> str:
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
    held = (r.get("reconstruct_heldout") or {}).get("fscore") or {}
    if held:
        steps = ((r.get("details") or {}).get("generator_recipe") or {}).get("reconstruct_refine_steps")
        lines += ["", "Held-out species at rest, transferred and reconstructed into the transferred "
                  "generator's shape-latent model (`stage=reconstruct`"
                  + (f", `reconstruct.refine_steps={steps}`" if steps else "") + "): F-score@0.01 "
                  + ", ".join(f"{n} {f:.3f}" for n, f in sorted(held.items())) + "."]
    return "\n".join(lines)


TABLES = {"animals": animals, "cli": cli, "autogc": autogc, "condition": condition, "ddp": ddp, "deform": deform, "demo": demo,
          "editor": editor, "extract": extract, "fit": fit, "fit_ablation": fit_ablation,
          "generate": generate, "geometry": geometry, "reconstruct": reconstruct,
          "sparse_settings": sparse_settings, "transfer": transfer, "up_axis": up_axis}


# ---- the README's "Results at a glance": one line per bench, from the same results ------------
def sci(x: float, exp: int = -3) -> str:
    """x in units of 10^exp: sci(6.6e-3) -> '6.60e-3'."""
    return f"{x / 10.0 ** exp:.2f}e{exp}"


def _glance_demo(r):
    m, f = r["measured"], r["steps"]["fit"]
    return (f"`make demo` on a fresh clone: {m['make_demo_wall_s']:.0f} s, setup included; fit CD "
            f"{sci(f['cd'], -4)}, F-score {f['fscore']:.3f}; edit eps_V "
            f"{pct(r['steps']['edit']['eps_v'], 3)}")


def _glance_fit(r):
    n, d = r["methods"]["ngc"], r["methods"]["deepsdf"]
    return (f"{len(r['shapes'])} shapes, {r['steps']} steps: NGC CD {sci(n['cd'], -4)}, NC "
            f"{n['nc']:.3f}, F {n['fscore']:.3f}; DeepSDF, same budget: {sci(d['cd'], -4)}, "
            f"{d['nc']:.3f}, {d['fscore']:.3f}")


def _glance_fit_ablation(r):
    runs = r["runs"]
    best = max(runs, key=lambda k: runs[k]["fscore"])
    b = runs["baseline"]
    return (f"{len(runs)} recipes screened; best `{best}` against `baseline`: F {b['fscore']:.3f} "
            f"-> {runs[best]['fscore']:.3f}, fragments {b['fragments']} -> "
            f"{runs[best]['fragments']}")


def _glance_deform(r):
    m = r["mean"]
    return (f"volume change NGC {pct(m['ngc']['eps_v'])} vs ARAP {pct(m['arap']['eps_v'])} (mean "
            f"of {len(r['cases'])} edits); edit to mesh at 256^3 {r['edit_to_mesh_s_256']:.2f} s vs "
            f"ARAP {r['arap_s_matched']:.2f} s")


def _glance_extract(r):
    c = next(c for c in r["cases"] if c["shape"] == "creature" and c["resolution"] == 256)
    return (f"creature at 256^3: 1/{1 / c['sparse_over_dense_evals']:.0f} of the dense "
            f"evaluations, {c['sparse_s']:.2f} s, "
            + ("mesh identical to the reference" if c["identical_mesh"] else
               f"{c['faces_differing']} faces differ from the reference"))


def _glance_sparse_settings(r):
    t = r["summary"]["track"]
    return f"default settings: {t['identical']} of {t['cases']} fitted meshes identical to the reference"


def _glance_reconstruct(r):
    return f"held-out creatures into the generator: CD {r['ratio']['mean']:.2f}x a direct fit"


def _glance_generate(r):
    g, t = r["generated"], r["train_set"]
    return (f"MMD-CD {sci(g['mmd_cd'])}, COV {pct(g['cov_cd'], 1)}, 1-NNA {pct(g['nna_cd'], 1)} "
            f"(training meshes {sci(t['mmd_cd'])}, {pct(t['cov_cd'], 1)}, {pct(t['nna_cd'], 1)})")


def _glance_condition(r):
    return (f"GC error {r['gc_err']:.3f} std; Chamfer to the source {sci(r['cd_conditional'])} vs "
            f"{sci(r['cd_unconditional'])} unconditioned")


def _glance_autogc(r):
    t, c = r["targets"], r["creatures"]
    return (f"{len(r['meshes'])} meshes, coverage >= {pct(t['coverage_min'], 2)}, at most "
            f"{t['time_s_max']:.1f} s each; {pct(c['part_single_gc_mean'], 1)} of a creature part "
            f"in one GC")


def _glance_editor(r):
    pre = [c["preview_s"] for c in r["cases"]]
    ref = [c["refine_s"] for c in r["cases"]]
    line = (f"an interaction to its preview in {span(pre)} s, refined at "
            f"{r['settings']['refine_resolution']}^3 in {span(ref)} s (server side)")
    drawn = [c["preview_s"] for c in r.get("browser", []) if c["preview_s"] is not None]
    if drawn:
        line += f"; drawn in headless Chromium {span(drawn)} s after the input"
    return line


def _glance_geometry(r):
    line = (f"relative coordinates at {r['relcoords_points_per_s_wall_all_cores'] / 1e6:.1f}M "
            f"points/s, round trip {r['roundtrip_err_newton']:.1e}")
    if "closest_point_excess_max" in r:
        line += f"; foot point within {r['closest_point_excess_max']:.0e} of the brute force's"
    return line


def _glance_ddp(r):
    return f"2 CPU processes: {r['speedup_samples_per_s']:.2f}x the samples per second of one"


def _glance_up_axis(r):
    t = r["totals"]
    return f"up axis right in {t['right']} of {t['orientations']} orientations"


def _glance_animals(r):
    c = r["clips"]
    return (f"{r['n_train']} posed animals: vs held-out clips 1-NNA {pct(c['generated']['nna_cd'], 1)}"
            f" (ceiling {pct(c['train_set']['nna_cd'], 1)}, floor {pct(c['noise']['nna_cd'], 1)});"
            f" rig GCs purity >= {pct(r['purity_worst'], 1)}; rest-pose fits F >= "
            f"{r['fit_fscore_min']:.3f}")


def _glance_transfer(r):
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
    return line


def _glance_cli(r):
    rej = r["reject_s"].values()
    return (f"bad input rejected in {span(list(rej))} s; an edit at 128^3 {r['edit_s_128']:.1f} s "
            f"end to end; `--help` {r['help_s']:.1f} s")


GLANCE = {"demo": _glance_demo, "fit": _glance_fit, "fit_ablation": _glance_fit_ablation,
          "deform": _glance_deform, "extract": _glance_extract,
          "sparse_settings": _glance_sparse_settings, "reconstruct": _glance_reconstruct,
          "generate": _glance_generate, "condition": _glance_condition, "animals": _glance_animals,
          "transfer": _glance_transfer, "autogc": _glance_autogc, "editor": _glance_editor,
          "cli": _glance_cli, "geometry": _glance_geometry, "ddp": _glance_ddp,
          "up_axis": _glance_up_axis}


def glance(results: Path = RESULTS) -> str:
    """The README's results table: one headline per bench that has a result."""
    rows = []
    for name, fn in GLANCE.items():
        path = Path(results) / f"{name}.json"
        if path.is_file():
            rows.append([f"[{name}](bench/README.md#{name})", fn(json.loads(path.read_text()))])
    return "\n".join(rows_table(["benchmark", "headline (latest result)"], rows)) + "\n"


def scalars(res: dict) -> str:
    """A bench without a table of its own here yet: its top-level numbers, strings and
    booleans as a key / value table."""
    rows = [[f"`{k}`", f"{v:.4g}" if isinstance(v, float) else v] for k, v in res.items()
            if isinstance(v, (int, float, str, bool)) and k != "machine"]
    return "\n".join(rows_table(["key", "value"], rows))


def table(name: str, res: dict) -> str:
    """The bench's tables from its result (`scalars` for a bench not in TABLES)."""
    return TABLES.get(name, scalars)(res)


def block(name: str, results: Path = RESULTS) -> str:
    """What bench/README.md holds between the markers of `name` (`glance`: the project
    README's results table)."""
    if name == "glance":
        return glance(results)
    path = Path(results) / f"{name}.json"
    if not path.is_file():
        return f"No result yet: run `make bench-{name.replace('_', '-')}`.\n"
    res = json.loads(path.read_text())
    return f"{table(name, res)}\n\n{machine_line(name, res)}\n"


def render(text: str, results: Path = RESULTS) -> str:
    """`text` (bench/README.md) with every table block regenerated."""
    def one(m):
        return m.group(1) + block(m.group("name"), results) + m.group(4)
    return BLOCK.sub(one, text)


def blocks_in(text: str) -> list[str]:
    return [m.group("name") for m in BLOCK.finditer(text)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if a page is stale")
    args = ap.parse_args(argv)
    stale = 0
    for page in PAGES:
        old = page.read_text()
        new = render(old)
        if new == old:
            continue
        name = str(page.relative_to(ROOT))
        if args.check:
            sys.stdout.writelines(difflib.unified_diff(
                old.splitlines(True), new.splitlines(True), name, "generated"))
            stale = 1
            continue
        sys.path.insert(0, str(ROOT))
        from bench._harness import write_atomic

        write_atomic(page, new)
        print(f"rewrote {name}: {', '.join(blocks_in(new))}")
    return stale


if __name__ == "__main__":
    sys.exit(main())
