"""How fast the commands answer, as a user types them, with PYTHONDONTWRITEBYTECODE=1 set.

reject_s: seconds from starting a command with a bad input until it exits (each must exit 2:
checked); edit_s_128: `edit.py run=<fit run of the ant> edit=posed_ant_leg
extract.resolution=128` end to end (picture included), with the bytecode the Makefile's setup
writes; edit_s_128_no_bytecode: the same with no bytecode and no numba kernel cache (a fresh
install without that step); help_s: the slowest `--help` of train.py, edit.py and sample.py;
malformed_mesh_s: `train.py stage=fit data=folder` on each of the fifteen malformed mesh files
of tests/app/malformed_meshes.py (each must exit 2: checked), malformed_mesh_slowest_s the
slowest of them;
setup_s_added: what `python -m ngc_gen.app.runtime.bytecode` (the setup step) takes on empty caches.

The bytecode cases run with PYTHONPYCACHEPREFIX and NUMBA_CACHE_DIR pointing at folders of this
bench (empty, or filled by the setup step), so nothing of the checkout's own __pycache__ is read
or changed.
Each figure is the median of `--repeat` runs. Writes bench/results/cli.json.

    python -m bench.cli [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench._harness import Bench, cached_run_fit
from bench._tables import rows_table, span

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
TARGET_REJECT_S, TARGET_EDIT_S = 2.0, 6.0


def fitted_ant() -> Path:
    """A fit run of the ant (model=small, 300 steps) from the bench's fit cache."""
    from ngc_gen.app.runtime.config import compose_config

    cfg = compose_config(overrides=[
        "stage=fit", "data=ant", "model=small", "trainer.max_steps=300",
        "extract.resolution=64", "trainer.enable_progress_bar=false", "logger=csv",
        "threads=1"])
    return cached_run_fit("cli", cfg, label="ant, small, 300 steps").run_dir


def bad_inputs(tmp: Path, fit: Path) -> dict[str, list[str]]:
    """case -> command line (script, args...) with one bad input each."""
    (tmp / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (tmp / "ball.yaml").write_text("name: ball\nmesh: gone.ply\ngcs: [{name: a}]\n")
    (tmp / "prog.yaml").write_text("name: p\nops: [{op: twist, gc: leg_l1, t: 1.0, "
                                   "degrees: '30'}]\n")
    (tmp / "fake.ckpt").write_bytes(b"not a checkpoint")
    out = f"hydra.run.dir={tmp}/run"
    return {
        "train_unknown_stage": ["train.py", "stage=train", out],
        "train_bad_max_steps": ["train.py", "stage=fit", "trainer.max_steps=lots", out],
        "train_empty_mesh": ["train.py", "stage=prepare", "data=folder", f"data.path={tmp}",
                             out],
        "train_missing_mesh": ["train.py", "stage=prepare", "data=ant",
                               f"data.annotations=[{tmp}/ball.yaml]", out],
        "train_missing_run": ["train.py", "stage=diffusion", f"shape_latent_run={tmp}/none",
                              out],
        "train_resolution_100000": ["train.py", "stage=fit", "extract.resolution=100000", out],
        "edit_unknown_op": ["edit.py", f"run={fit}", f"program_file={tmp}/prog.yaml",
                            f"out_dir={tmp}/e"],
        "edit_not_a_checkpoint": ["edit.py", f"run={tmp}/fake.ckpt", "edit=posed_ant_leg",
                                  f"out_dir={tmp}/e"],
        "edit_resolution_100000": ["edit.py", f"run={fit}", "edit=posed_ant_leg",
                                   "extract.resolution=100000", f"out_dir={tmp}/e"],
        "editor_remote_host": ["edit.py", f"run={fit}", "viewer=true", "editor.host=0.0.0.0"],
        "sample_n_two": ["sample.py", "n=two", f"run={fit}", f"out_dir={tmp}/s"],
        "sample_n_zero": ["sample.py", "n=0", f"out_dir={tmp}/s"],
        "sample_fit_run": ["sample.py", f"run={fit}", f"out_dir={tmp}/s"],
        "sample_resolution_100000": ["sample.py", "extract.resolution=100000",
                                     f"out_dir={tmp}/s"],
    }


def timed(argv: list[str], env: dict, expect: int | None = None) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([PY, str(ROOT / argv[0]), *argv[1:]], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    seconds = time.perf_counter() - t0
    if expect is not None and r.returncode != expect:
        raise SystemExit(f"{' '.join(argv)}: exit {r.returncode}, expected {expect}\n"
                         f"{r.stderr[-2000:]}")
    return seconds


def median(fn, repeat: int) -> float:
    return statistics.median(fn() for _ in range(repeat))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    bench = Bench("cli")
    from tests.app.malformed_meshes import write_malformed

    fit = fitted_ant()
    work = Path(tempfile.mkdtemp(prefix="ngc_bench_cli_"))
    try:
        warm, cold = work / "pyc_setup", work / "pyc_none"
        base = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "OMP_NUM_THREADS": "1",
                "PYTHONPATH": str(ROOT)}
        # numba's kernel cache too: filled by the setup step, or empty before each cold run
        env_warm = {**base, "PYTHONPYCACHEPREFIX": str(warm),
                    "NUMBA_CACHE_DIR": str(work / "numba_setup")}
        env_cold = {**base, "PYTHONPYCACHEPREFIX": str(cold),
                    "NUMBA_CACHE_DIR": str(work / "numba_none")}

        t0 = time.perf_counter()  # the setup step on an empty bytecode cache
        subprocess.run([PY, "-m", "ngc_gen.app.runtime.bytecode"], cwd=ROOT, env=env_warm, check=True,
                       capture_output=True)
        setup_s = time.perf_counter() - t0

        reject = {}
        for case, cmd in bad_inputs(work, fit).items():
            reject[case] = median(lambda: timed(cmd, env_warm, expect=2), args.repeat)
            print(f"reject {case}: {reject[case]:.2f} s", flush=True)
        malformed = {}
        for case, (path, _) in write_malformed(work / "malformed").items():
            cmd = ["train.py", "stage=fit", "data=folder", f"data.path={path.parent}",
                   f"hydra.run.dir={work}/run"]
            malformed[case] = median(lambda: timed(cmd, env_warm, expect=2), args.repeat)
            print(f"malformed {case}: {malformed[case]:.2f} s", flush=True)
        help_by = {s: median(lambda: timed([s, "--help"], env_warm, expect=0), args.repeat)
                   for s in ("train.py", "edit.py", "sample.py")}
        edit = ["edit.py", f"run={fit}", "edit=posed_ant_leg", "extract.resolution=128",
                f"out_dir={work}/edit", "threads=1"]
        edit_warm = median(lambda: timed(edit, env_warm, expect=0), args.repeat)
        def cold_edit():  # a fresh install without the setup step: no .pyc, no kernel cache
            shutil.rmtree(work / "numba_none", ignore_errors=True)
            return timed(edit, env_cold, expect=0)

        edit_cold = median(cold_edit, args.repeat)
        shutil.rmtree(cold, ignore_errors=True)
        print(f"edit at 128^3: {edit_warm:.2f} s with bytecode, {edit_cold:.2f} s without; "
              f"setup adds {setup_s:.1f} s; --help {max(help_by.values()):.2f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    result = {
        "reject_s": {k: round(v, 3) for k, v in reject.items()},
        "malformed_mesh_s": {k: round(v, 3) for k, v in malformed.items()},
        "malformed_mesh_slowest_s": round(max(malformed.values()), 3),
        "edit_s_128": round(edit_warm, 3),
        "help_s": round(max(help_by.values()), 3),
        "setup_s_added": round(setup_s, 2),
        "edit_s_128_no_bytecode": round(edit_cold, 3),
        "help_s_by_script": {k: round(v, 3) for k, v in help_by.items()},
        "repeat": args.repeat,
        "targets": {"reject_s": TARGET_REJECT_S, "edit_s_128": TARGET_EDIT_S,
                    "malformed_mesh_slowest_s": TARGET_REJECT_S},
        "met": {"reject_s": max(reject.values()) <= TARGET_REJECT_S,
                "malformed_mesh_slowest_s": max(malformed.values()) <= TARGET_REJECT_S,
                "edit_s_128": edit_warm <= TARGET_EDIT_S},
    }
    print(bench.write(result))
    return 0


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
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
    bad = r.get("malformed_mesh_s")
    if bad:
        ok = sum(v <= t["malformed_mesh_slowest_s"] for v in bad.values())
        lines += ["", f"Malformed mesh files (`train.py stage=fit data=folder` on each of the "
                      f"{len(bad)} of tests/app/malformed_meshes.py): exit 2 after "
                      f"{span(list(bad.values()))} s, slowest {r['malformed_mesh_slowest_s']:.2f}"
                      f" s; {ok} of {len(bad)} within the {t['malformed_mesh_slowest_s']:g} s "
                      "target."]
    return "\n".join(lines)


def headline(r):
    rej = r["reject_s"].values()
    return (f"bad input rejected in {span(list(rej))} s; an edit at 128^3 {r['edit_s_128']:.1f} s "
            f"end to end; `--help` {r['help_s']:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
