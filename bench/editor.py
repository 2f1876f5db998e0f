"""The editor's response time: from an interaction to the updated mesh in the scene.

    python -m bench.editor [--ckpt <fit checkpoint>] [--steps 1500] [--repeats 3] [--threads 1]
                           [--no-screenshot]

Input: the ant and a procedural creature fitted together (`train.py stage=fit data=demo
model=small`; the fit is kept in the bench's fit cache, .cache/bench/fits/editor, keyed by its
whole recipe: config, data, steps; --refit fits again; or pass --ckpt of such a fit). An
`EditorServer` runs in this process (no browser during the timings: a software-GL browser would
take the same cores), and each interaction goes through the code path of its GUI callback
(session interaction, then the server's overlay / controls / mesh loop):
- drag: a control point of a leg moved (op `move`), then the drag released;
- radius / twist: a key slider moved (ops `scale`, `twist`), then released;
- pose: a leg turned by handles about its start (op `handles`), then released.
preview_s: interaction -> preview mesh (conf/editor preview_resolution) in the scene;
refine_s: release -> refined mesh (refine_resolution) in the scene; both with conf/editor's
extraction settings. Each figure is the median of --repeats interactions with new values.
The issue's target: preview_s <= 0.3 s.

Then (unless --no-screenshot) bench/results/editor.png: the editor page in headless Chromium,
made by the browser test's steps (`tests.app.editor.browser`), on the ant with a posed leg.

Baseline measured in the same run: extract_preview_s, the preview extraction alone (no
editor), so preview_s / extract_preview_s is the editor's overhead on a loaded machine.

Browser side (unless --no-browser; needs /usr/bin/chromium): the same server with the page open
in headless Chromium (Playwright); a value is typed into a number box of the panel (twist,
radius, stretch factor, pose angle on the ant's leg) and the page records the input event and
when the preview and the refined mesh of that edit are drawn (two animation frames after their
status line arrives). Target: the preview drawn within 0.5 s at load < 1. The first two edits
after the page opens (a twist) come first and are reported apart (`browser_first_edits`): the
page compiles what it draws the first time, so they are slower than the steady state.

Writes bench/results/editor.json: {cases: [{shape, interaction, preview_s, refine_s, n_faces,
extract_preview_s}], browser: [{interaction, preview_s, refine_s, server_preview_s,
server_refine_s}], browser_first_edits: [{preview_s, refine_s, ...}], settings, machine}
(bench/_harness.py).
"""
from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from bench._harness import Bench, cached_run_fit
from bench._tables import rows_table, span

ROOT = Path(__file__).resolve().parents[1]
RUN_DIR = ROOT / "bench/runs/editor"
RESULTS = ROOT / "bench/results"
SHAPES = {"ant": "leg_l1", "creature_0000": "leg_fl"}  # shape -> the GC the interactions edit


def fitted(steps: int, refit: bool = False, resolution: int = 64) -> Path:
    """The ant + 3 creatures fit of `make demo` at `steps` steps: from the bench's fit cache
    while its recipe (the whole config, the shapes' data) is unchanged, else fitted now."""
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=[
        "stage=fit", "data=demo", "model=small", f"trainer.max_steps={steps}",
        f"extract.resolution={resolution}", "trainer.enable_progress_bar=false", "logger=csv"])
    return cached_run_fit("editor", cfg, refit=refit).run_dir / "checkpoints/last.ckpt"


def interactions(session, gc: str):
    """{name: (act(i) -> Outcome)}: the i-th repeat of each interaction, each with a new value."""
    import numpy as np

    g = session.shape.gcs[session.shape.index(gc)]
    p = g.curve.points[-1].copy()
    r = 0.5 * sum(g.keys[-1].radii)
    return {
        "drag control point": lambda i: session.move_point(
            gc, len(g.curve.points) - 1, p + np.array([0.0, 0.0, 0.02 * (i + 1)])),
        "radius slider": lambda i: session.set_radius(gc, len(g.keys) - 1, r * (1.1 + 0.1 * i)),
        "twist slider": lambda i: session.set_twist(gc, 0, 20.0 * (i + 1)),
        "pose limb": lambda i: session.pose(gc, "normal", 10.0 * (i + 1)),
    }


def time_case(server, act, repeats: int) -> dict:
    """Median seconds interaction -> preview in the scene, release -> refined in the scene."""
    loop, prev, ref = server.loop, [], []
    faces = 0
    for i in range(repeats):
        t0 = time.perf_counter()
        out = server.apply(act(i))
        if not out.ok:
            raise RuntimeError(out.message)
        version = server.session.version
        shown = loop.wait_for(version, loop.preview)
        prev.append(shown.at - t0)
        t1 = time.perf_counter()
        loop.released()
        shown = loop.wait_for(version, loop.refine)
        ref.append(shown.at - t1)
        faces = shown.n_faces
    # baseline in the same run: the preview extraction alone (Shape.mesh, no editor), so
    # preview_s / extract_preview_s is the editor's own overhead whatever the machine's load
    session, bare = server.session, []
    shape = session.snapshot()[1]
    for _ in range(repeats):
        t0 = time.perf_counter()
        session.mesh(loop.preview, shape=shape, **loop.extract_kw[loop.preview])
        bare.append(time.perf_counter() - t0)
    return {"preview_s": statistics.median(prev), "refine_s": statistics.median(ref),
            "n_faces": faces, "extract_preview_s": statistics.median(bare),
            "preview_all_s": prev, "refine_all_s": ref}


# in the page: the time of the first input event (the box's value changed, or Enter) since the
# bench cleared it, and per status line "mesh: version V, R^3" the time it appeared and the time
# two animation frames later (the frame that draws the mesh the same message brought)
INSTRUMENT_JS = """() => {
  const rec = window.__ngc = {input: null, shown: {}};
  const first = () => { if (rec.input === null) rec.input = performance.now(); };
  document.addEventListener('input', first, true);
  document.addEventListener('keydown', e => { if (e.key === 'Enter') first(); }, true);
  const re = /mesh: version (\\d+), (\\d+)\\^3, \\d+ faces, ([\\d.]+) s/;
  new MutationObserver(() => {
    const m = document.body.textContent.match(re);  // not innerText: it forces a layout per mutation
    if (!m) return;
    const key = m[1] + ':' + m[2];
    if (key in rec.shown) return;
    const t = performance.now();
    rec.shown[key] = {status: t, drawn: null, server_s: parseFloat(m[3])};
    requestAnimationFrame(() => requestAnimationFrame(() => { rec.shown[key].drawn = performance.now(); }));
  }).observe(document.body, {subtree: true, childList: true, characterData: true});
}"""
BROWSER_TARGET_S = 0.5  # the issue's: the preview drawn within 0.5 s in headless Chromium


def browser_inputs(session, gc: str):
    """{interaction: (number box label, value of repeat i)}: what a user types in the panel."""
    g = session.shape.gcs[session.shape.index(gc)]
    r = 0.5 * sum(g.keys[0].radii)
    return {"twist box": ("twist (deg)", lambda i: 20.0 * (i + 1)),
            "radius box": ("radius", lambda i: round(r * (1.1 + 0.1 * i), 3)),
            "stretch box": ("factor", lambda i: round(1.1 + 0.05 * i, 2)),
            "pose box": ("angle (deg)", lambda i: 5.0 * (i + 1))}


def browser_latency(cfg, gc: str, repeats: int) -> tuple[list[dict], list[dict]]:
    """Per interaction typed into the page (headless Chromium): input event -> preview mesh
    drawn and -> refined mesh drawn, in the browser's clock, beside the server's extraction
    seconds the same status lines report; medians of `repeats`. Also the rows of the first two
    edits after the page opened (twist), which come before the cases."""
    from playwright.sync_api import sync_playwright

    from tests.app.editor import browser
    from ngc_gen.app.editor.server import EditorServer
    from ngc_gen.app.editor.start import open_session

    session, latent = open_session(cfg)
    server = EditorServer(session, cfg.editor, latent, out_dir=RUN_DIR / "editor")
    pre, ref = int(cfg.editor.preview_resolution), int(cfg.editor.refine_resolution)
    out, first = [], []
    try:
        with sync_playwright() as p:
            chrome = browser.launch(p)
            page = chrome.new_page(viewport=browser.VIEWPORT)
            browser.open_editor(page, server.url, ref, timeout_s=300)
            page.evaluate(INSTRUMENT_JS)
            server.select(gc)

            def measure(label: str, value: float) -> dict | None:
                """Type `value` into the box `label`; the row of figures, None if refused."""
                version = session.version + 1
                page.evaluate("window.__ngc.input = null")
                browser.set_number(page, label, value)
                try:
                    browser.wait_for_mesh(page, version, ref, 60)
                except Exception as e:  # refused (a limit) or lost: say which, go on
                    print(f"browser {label} = {value}: no mesh of version {version} "
                          f"({type(e).__name__}); editor says: {session.message}")
                    return None
                page.wait_for_function(
                    "k => { const s = window.__ngc.shown[k]; return !!(s && s.drawn); }",
                    arg=f"{version}:{ref}", timeout=30_000)
                rec = page.evaluate("window.__ngc")
                shown_p, shown_r = rec["shown"].get(f"{version}:{pre}"), \
                    rec["shown"][f"{version}:{ref}"]
                t_in = rec["input"]
                if not session.ops or session.ops[-1].get("gc") != gc:
                    raise RuntimeError(f"{label}: the page's input made no op on {gc}: "
                                       f"{session.message}")
                return {"preview_s": None if not shown_p or shown_p["drawn"] is None
                        else (shown_p["drawn"] - t_in) / 1e3,
                        "refine_s": (shown_r["drawn"] - t_in) / 1e3,
                        "preview_status_s": None if not shown_p
                        else (shown_p["status"] - t_in) / 1e3,
                        "server_preview_s": shown_p and shown_p["server_s"],
                        "server_refine_s": shown_r["server_s"]}

            # the first edits after the page opens are slower (the page compiles what it draws
            # the first time: 0.64 -> 0.45 -> 0.38 s over the first three, measured): reported
            # on their own, so the cases below are the steady state a user works in
            first = [r for r in (measure("twist (deg)", 5.0 * (k + 1)) for k in range(2)) if r]
            for name, (label, value) in browser_inputs(session, gc).items():
                rows = [r for r in (measure(label, value(i)) for i in range(repeats)) if r]
                if not rows:
                    continue

                def med(k):
                    v = [r[k] for r in rows if r[k] is not None]
                    return statistics.median(v) if v else None

                case = {"shape": session.base.name, "gc": gc, "interaction": name,
                        **{k: med(k) for k in rows[0]}, "all": rows}
                out.append(case)
                ok = case["preview_s"] is not None and case["preview_s"] <= BROWSER_TARGET_S
                print(f"browser {name:12s} preview drawn {case['preview_s']} s "
                      f"({'ok' if ok else 'over the 0.5 s target'}), refined drawn "
                      f"{case['refine_s']:.2f} s; server extraction {case['server_preview_s']} "
                      f"/ {case['server_refine_s']} s", flush=True)
            chrome.close()
    finally:
        server.stop()
    return out, first


def screenshot(cfg, path: Path) -> None:
    """editor.png: the browser test's steps on the ant, a leg posed through the page."""
    from playwright.sync_api import sync_playwright

    from tests.app.editor import browser
    from ngc_gen.app.editor.server import EditorServer
    from ngc_gen.app.editor.start import open_session

    session, latent = open_session(cfg)
    server = EditorServer(session, cfg.editor, latent, out_dir=RUN_DIR / "editor")
    try:
        with sync_playwright() as p:
            chrome = browser.launch(p)
            page = chrome.new_page(viewport=browser.VIEWPORT)
            browser.open_editor(page, server.url, cfg.editor.refine_resolution, timeout_s=120)
            server.apply(session.pose("leg_l1", "normal", 35.0))  # what the pose slider does
            server.apply(session.pose("leg_r3", "normal", -30.0))
            server.select("leg_l1")
            version = session.version + 1
            browser.set_number(page, "twist (deg)", 60)  # through the page: the leg's key 0
            browser.wait_for_mesh(page, version, cfg.editor.refine_resolution, 120)
            time.sleep(1.0)
            RESULTS.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(path))
            chrome.close()
    finally:
        server.stop()
    print(f"wrote {path}")


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ckpt", default=None, help="a demo fit's checkpoint (default: fit once)")
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--refit", action="store_true", help="fit again even if the cache has it")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--no-screenshot", action="store_true")
    ap.add_argument("--no-browser", action="store_true",
                    help="leave out the browser-side latency (headless Chromium)")
    return ap.parse_args()


def main() -> None:
    args = parse_args()
    bench = Bench("editor")

    import torch

    torch.set_num_threads(args.threads)
    from tests.app.editor import browser
    from ngc_gen.app.editor.server import EditorServer
    from ngc_gen.app.editor.start import open_session
    from ngc_gen.app.runtime.config import compose_config

    ckpt = Path(args.ckpt) if args.ckpt else fitted(args.steps, args.refit)
    cases = []
    settings = None
    for shape, gc in SHAPES.items():
        cfg = compose_config("edit", [f"run={ckpt}", "viewer=true", f"shape={shape}",
                                      f"editor.port={browser.free_port()}",
                                      f"editor.out_dir={RUN_DIR / 'editor'}"])
        settings = {k: cfg.editor[k] for k in ("preview_resolution", "refine_resolution",
                                               "refine_delay_s")}
        preview_kw, refine_kw = (dict(cfg.editor[k]) for k in ("preview_extract",
                                                                "refine_extract"))
        session, latent = open_session(cfg)
        server = EditorServer(session, cfg.editor, latent, out_dir=RUN_DIR / "editor")
        try:
            server.loop.wait_for(0, server.loop.refine, timeout=300)  # the opening mesh
            for name, act in interactions(session, gc).items():
                r = time_case(server, act, args.repeats)
                cases.append({"shape": shape, "gc": gc, "interaction": name, **r})
                ok = "ok" if r["preview_s"] <= 0.3 else "over the 0.3 s target"
                print(f"{shape:14s} {name:20s} preview {r['preview_s']:.3f} s ({ok}; "
                      f"{r['preview_s'] / r['extract_preview_s']:.2f}x the bare extraction), "
                      f"refine {r['refine_s']:.2f} s, {r['n_faces']} faces", flush=True)
        finally:
            server.stop()
    browser_cases, browser_first = [], []
    if not args.no_browser:
        if not browser.CHROMIUM.exists():
            print(f"no {browser.CHROMIUM}: the browser-side figures are left out")
        else:
            cfg = compose_config("edit", [f"run={ckpt}", "viewer=true", "shape=ant",
                                          f"editor.port={browser.free_port()}",
                                          "editor.environment=null",
                                          f"editor.out_dir={RUN_DIR / 'editor'}"])
            browser_cases, browser_first = browser_latency(cfg, SHAPES["ant"], args.repeats)
            for k, r in enumerate(browser_first):
                print(f"browser edit {k + 1} after the page opened: preview drawn "
                      f"{r['preview_s']} s, refined {r['refine_s']:.2f} s", flush=True)
    out = {"cases": cases, "browser": browser_cases, "browser_first_edits": browser_first,
           "settings": {**settings, "threads": args.threads, "repeats": args.repeats,
                        "fit_steps": None if args.ckpt else args.steps,
                        "browser_target_s": BROWSER_TARGET_S,
                        "checkpoint": os.path.relpath(ckpt, ROOT),
                        "preview_extract": preview_kw, "refine_extract": refine_kw,
                        "convention": "preview_s: interaction -> preview mesh in the scene; "
                                      "refine_s: release -> refined mesh in the scene; "
                                      "extract_preview_s: the preview extraction alone "
                                      "(baseline, same run); medians. browser: a value "
                                      "typed into the page's number box (headless Chromium, "
                                      "editor.environment=null) -> the preview / refined mesh "
                                      "drawn (two animation frames after its status line), in "
                                      "the page's clock; server_*_s: the server's extraction "
                                      "seconds for the same meshes"}}
    path = bench.write(out)
    m = bench.machine()
    print(f"load average {m['load_1min_before']} -> {m['load_1min_after']} (1 min) on "
          f"{m['cpus']} cores; wrote {path}")
    if not args.no_screenshot:
        cfg = compose_config("edit", [f"run={ckpt}", "viewer=true", "shape=ant",
                                      f"editor.port={browser.free_port()}",
                                      "editor.environment=null",
                                      f"editor.out_dir={RUN_DIR / 'editor'}"])
        screenshot(cfg, RESULTS / "editor.png")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
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


def headline(r):
    pre = [c["preview_s"] for c in r["cases"]]
    ref = [c["refine_s"] for c in r["cases"]]
    line = (f"an interaction to its preview in {span(pre)} s, refined at "
            f"{r['settings']['refine_resolution']}^3 in {span(ref)} s (server side)")
    drawn = [c["preview_s"] for c in r.get("browser", []) if c["preview_s"] is not None]
    if drawn:
        line += f"; drawn in headless Chromium {span(drawn)} s after the input"
    return line


if __name__ == "__main__":
    main()
