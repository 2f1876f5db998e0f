"""DDP step time on CPU: the same fit run as one process (trainer=cpu) and as two (trainer=ddp,
gloo), each process with one torch thread and the same batch per process.

    python -m bench.ddp [--steps 150] [--warmup 20] [--batch 4096] [--repeats 2]

Each run is the real command (`train.py stage=fit ...`); a callback (bench/_step_timer.py) records
the wall time of every optimizer step on every rank, and the first `warmup` steps are dropped.
One process and two processes run alternately `repeats` times, so both see the same drift of
the machine's load. Writes bench/results/ddp.json: step_s_1proc, step_s_2proc (median seconds
per optimizer step), step_ratio_2_to_1, samples_per_s_1proc / _2proc (batch x processes /
step time), speedup_samples_per_s, per-run medians, batch_per_process, steps_timed and the
machine record (bench/_harness.py; torch_threads: the 1 thread of each training process). The
machine is shared: compare the ratio, which both settings measured in the same minutes, not
absolute times.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench._harness import Bench, load_1min
from bench._tables import rows_table

ROOT = Path(__file__).resolve().parents[1]

def meshes(folder: Path) -> Path:
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    trimesh.creation.torus(major_radius=0.6, minor_radius=0.25).export(folder / "torus.ply")
    trimesh.creation.icosphere(subdivisions=3).export(folder / "ball.ply")
    return folder


def run(trainer: str, work: Path, tag: str, steps: int, batch: int) -> list[float]:
    """One `train.py stage=fit` run; the per-step seconds of its rank 0."""
    out = work / tag
    env = {**os.environ, "PYTHONPATH": str(ROOT),
           "OMP_NUM_THREADS": "1"}
    args = [sys.executable, str(ROOT / "train.py"), "stage=fit", f"trainer={trainer}",
            "data=folder", f"data.path={work / 'meshes'}", f"paths.cache_dir={work / 'cache'}",
            "prepare.n_samples=40000", f"batch_size={batch}", f"trainer.max_steps={steps}",
            "trainer.enable_progress_bar=false", "extract.resolution=16", "threads=1",
            "+callbacks.timer._target_=bench._step_timer.StepTimer",
            f"+callbacks.timer.out_dir={out}",
            f"hydra.run.dir={out / 'run'}"]
    r = subprocess.run(args, cwd=ROOT, env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{trainer} run failed:\n{r.stderr[-3000:]}")
    times = json.loads((out / "rank0.json").read_text())["times"]
    return [b - a for a, b in zip(times, times[1:])]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args()
    bench = Bench("ddp")
    runs = {"cpu": [], "ddp": []}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        meshes(work / "meshes")
        for k in range(a.repeats):
            for trainer in ("cpu", "ddp"):
                dt = run(trainer, work, f"{trainer}{k}", a.steps + a.warmup + 1, a.batch)
                runs[trainer].append(statistics.median(dt[a.warmup:]))
                print(f"{trainer} run {k}: {runs[trainer][-1] * 1e3:.1f} ms/step "
                      f"(load {load_1min()})", flush=True)
    one, two = statistics.median(runs["cpu"]), statistics.median(runs["ddp"])
    result = {
        "step_s_1proc": one, "step_s_2proc": two, "step_ratio_2_to_1": two / one,
        "samples_per_s_1proc": a.batch / one, "samples_per_s_2proc": 2 * a.batch / two,
        "speedup_samples_per_s": (2 * a.batch / two) / (a.batch / one),
        "runs_step_s": runs, "batch_per_process": a.batch, "steps_timed": a.steps,
        "warmup_steps": a.warmup, "threads_per_process": 1,
        "model": "small (conf/model/small.yaml), 2 shapes (torus 1 GC, ball 1 GC)",
        "convention": "median wall seconds per optimizer step of rank 0 after warm-up; "
                      "2 processes: gloo all-reduce of the gradients each step",
    }
    path = bench.write(result, torch_threads=1)
    m = bench.machine()
    print(f"1 process: {one * 1e3:.1f} ms/step ({a.batch / one:.0f} samples/s); 2 processes: "
          f"{two * 1e3:.1f} ms/step ({2 * a.batch / two:.0f} samples/s); step time x"
          f"{two / one:.2f}, throughput x{result['speedup_samples_per_s']:.2f}; load "
          f"{m['load_1min_before']} -> {m['load_1min_after']} on {m['cpus']} cores")
    print(f"wrote {path}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
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


def headline(r):
    return f"2 CPU processes: {r['speedup_samples_per_s']:.2f}x the samples per second of one"


if __name__ == "__main__":
    main()
