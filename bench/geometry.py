"""Geometry benchmark: relative-coordinate throughput and data preparation time per shape.

    python -m bench.geometry            # prints a table, writes bench/results/geometry.json

Throughput: 1M float32 points uniform in the bounding box of a curved, twisted 128-segment
Bezier GC, best of 3 after a warm-up: relcoords_points_per_s in CPU seconds of one thread
(time.process_time, robust to other jobs), relcoords_points_per_s_wall_all_cores in wall
seconds with every core (the fused kernel follows torch's thread count; target >= 1e7 on 2
cores, meaningful on an idle machine: the load average is recorded). Baseline in the same run:
the plain polyline projection over all 128 segments (the alternative docs/gcs.md describes), with its
round-trip error next to ours; round trips of float64 and of float32 points (target < 1e-5).
Closest points: the property test's generator and brute force (ngc_gen.geometry.closest_check:
random Bezier GCs of degrees 1-5, points inside and nearly equidistant from two arcs):
closest_point_excess_max, how much farther the kernel's foot point is than the brute force's
(target <= 1e-9), over closest_point_points points (>= 1e5).
Preparation: `prepare_shape` from scratch (empty cache) for 100k samples on the shipped shapes.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from bench._harness import Bench, load_1min
from bench._tables import count, rows_table

ROOT = Path(__file__).resolve().parents[1]

GC = {"name": "bench", "curve": {"type": "bezier", "points": [[-0.6, 0, 0], [-0.2, 0.4, 0.1],
                                                              [0.2, -0.3, 0.2], [0.6, 0.1, 0]]},
      "up": [0, 0, 1], "keys": [{"t": 0, "radii": [0.12, 0.09], "twist": 0},
                                {"t": 1, "radii": [0.07, 0.06], "twist": 90}],
      "caps": [0.06, 0.08]}


def best_of(fn, repeats=3):
    """Best CPU time of `repeats` calls after a warm-up. CPU seconds (process_time) with one
    torch thread measure the work itself; wall time on a shared machine measures the queue."""
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return min(times)


def polyline_relative(gc, q, chunk=1 << 14):
    """Baseline: project onto all segments of the 128-segment polyline, keep the nearest,
    offset in the frame at that parameter (no smooth-curve refinement)."""
    import torch

    x, ps = gc.polyline.x.float(), gc.polyline.s.float()
    A, AB = x[:-1], x[1:] - x[:-1]
    out = []
    for i in range(0, len(q), chunk):
        p = q[i:i + chunk]
        lam = (((p[:, None] - A) * AB).sum(-1) / (AB * AB).sum(-1)).clamp(0, 1)
        d = ((A + lam[..., None] * AB - p[:, None]) ** 2).sum(-1)
        j = d.argmin(1)
        lj = lam.gather(1, j[:, None])[:, 0]
        s = (ps[j] + lj * (ps[j + 1] - ps[j])).double()
        foot = (A[j] + lj[:, None] * AB[j]).double()
        t = gc.arc.t_of_s(s)
        _, _, N, B = gc.frame(s, t)
        r = gc.radii_at(t)
        off = p.double() - foot
        out.append(torch.stack([2 * t - 1, (off * N).sum(1) / r[:, 0], (off * B).sum(1) / r[:, 1]], 1))
    return torch.cat(out)


def bench_relcoords(n=1_000_000):
    import numpy as np
    import torch

    from ngc_gen.geometry import GeneralizedCylinder

    gc = GeneralizedCylinder.from_dict(GC)
    lo, hi = gc.bounds()
    rng = np.random.default_rng(0)
    q = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
    ours = best_of(lambda: gc.to_relative(q))
    torch.set_num_threads(os.cpu_count() or 1)  # wall time with every core (idle machine only)
    gc.to_relative(q)
    walls = []
    for _ in range(3):
        t0 = time.perf_counter()
        gc.to_relative(q)
        walls.append(time.perf_counter() - t0)
    wall_all = min(walls)
    load_wall = load_1min()
    torch.set_num_threads(1)
    qt = torch.from_numpy(q)
    base = best_of(lambda: polyline_relative(gc, qt), repeats=1)
    # round-trip error on points inside the tube, both methods
    rel = np.stack([rng.uniform(-1, 1, 200_000), rng.uniform(-.7, .7, 200_000),
                    rng.uniform(-.7, .7, 200_000)], 1)
    inside = gc.to_world(rel)
    err_ours = float(np.abs(gc.to_world(gc.to_relative(inside)) - inside).max())
    in32 = inside.astype(np.float32)
    err_32 = float(np.abs(gc.to_world(gc.to_relative(in32)) - in32).max())
    err_poly = float(np.abs(gc.to_world(polyline_relative(gc, torch.from_numpy(inside).float())
                                        .numpy()) - inside).max())
    return {"relcoords_points_per_s": n / ours, "relcoords_s_per_1M": ours,
            "relcoords_points_per_s_wall_all_cores": n / wall_all,
            "load_1min_at_wall_timing": load_wall,
            "polyline_points_per_s": n / base, "speedup_vs_polyline": base / ours,
            "roundtrip_err_newton": err_ours, "roundtrip_err_newton_float32": err_32,
            "roundtrip_err_polyline": err_poly}


def bench_closest_point():
    from ngc_gen.geometry.closest_check import closest_point_check

    return closest_point_check()


def bench_prepare():
    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
    from ngc_gen.data.prepare import PrepareSettings, prepare_shape

    shapes = [load_annotation(ROOT / "datasets/ant/ant.yaml"),
              load_annotation(ROOT / "datasets/airplane/airplane.yaml"),
              auto_annotation("pyvista:ant.ply", settings=AutoGCSettings.from_yaml(method="axis"))]
    try:
        from ngc_gen.data.procedural.creatures import make_creature  # noqa: F401
        from ngc_gen.data.procedural.creatures import build_creatures
        with tempfile.TemporaryDirectory() as d:
            build_creatures(Path(d), 2, seed=0)
            shapes += [load_annotation(p) for p in sorted(Path(d).glob("*.yaml"))]
            return _time_prepare(shapes, PrepareSettings.from_yaml(n_samples=100_000), prepare_shape)
    except ImportError:
        return _time_prepare(shapes, PrepareSettings.from_yaml(n_samples=100_000), prepare_shape)


def _time_prepare(shapes, settings, prepare_shape):
    import numpy as np

    per = {}
    with tempfile.TemporaryDirectory() as cache:
        for ann in shapes:
            t0 = time.process_time()
            prep = prepare_shape(ann, settings, Path(cache))
            per[f"{ann.name} ({len(ann.gcs)} GC)"] = {"s": time.process_time() - t0,
                                                     "coverage": float(prep.coverage)}
    return {"prepare_s_per_shape": float(np.mean([v["s"] for v in per.values()])),
            "prepare_n_samples": settings.n_samples, "prepare_shapes": per}


def main():
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    import torch

    torch.set_num_threads(1)  # one thread, CPU seconds: robust to other jobs on the machine
    bench = Bench("geometry")   # the machine record (bench/_harness.py) is added on writing
    res = {"omp_wait_policy": os.environ.get("OMP_WAIT_POLICY")}
    res.update(bench_relcoords())
    res.update(bench_closest_point())
    res.update(bench_prepare())
    print(f"machine load (1 min average) at start: {bench.load_before}"
          f" on {os.cpu_count()} cores: timings are only meaningful on an idle machine")
    print(f"relative coords : {res['relcoords_points_per_s'] / 1e6:.2f} M points/s per core "
          f"(CPU time, float32, 1M points, 128 segments)")
    print(f"  wall time with all {os.cpu_count()} cores: "
          f"{res['relcoords_points_per_s_wall_all_cores'] / 1e6:.2f} M points/s (target >= 10)")
    print(f"  baseline polyline over all segments: {res['polyline_points_per_s'] / 1e6:.2f} M/s "
          f"-> ours is {res['speedup_vs_polyline']:.1f}x faster")
    print(f"  round-trip error: newton {res['roundtrip_err_newton']:.2e} (float32 points "
          f"{res['roundtrip_err_newton_float32']:.2e}), polyline "
          f"{res['roundtrip_err_polyline']:.2e}")
    print(f"closest point   : foot at most {res['closest_point_excess_max']:.1e} farther than the "
          f"brute force's over {res['closest_point_points']} points in "
          f"{res['closest_point_gcs']} random GCs (target <= 1e-9)")
    print(f"prepare         : {res['prepare_s_per_shape']:.2f} s/shape for "
          f"{res['prepare_n_samples']} samples (target <= 2)")
    for k, v in res["prepare_shapes"].items():
        print(f"  {k:28s} {v['s']:.2f} s  coverage {v['coverage']:.5f}")
    out = bench.write(res)
    print(f"saved {out.relative_to(ROOT)}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
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


def headline(r):
    line = (f"relative coordinates at {r['relcoords_points_per_s_wall_all_cores'] / 1e6:.1f}M "
            f"points/s, round trip {r['roundtrip_err_newton']:.1e}")
    if "closest_point_excess_max" in r:
        line += f"; foot point within {r['closest_point_excess_max']:.0e} of the brute force's"
    return line


if __name__ == "__main__":
    main()
