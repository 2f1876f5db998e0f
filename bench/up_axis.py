"""The up-axis rule of the pictures (`ngc_gen.viz.camera.detect_up`, `viz.up: auto`), measured.

    python -m bench.up_axis [--creatures 64] [--creatures-dir DIR]

Meshes with a known up: pyvista's ant (+y), airplane (+z) and the procedural creatures (+z;
read from DIR, default .cache/datasets/creatures_n64_s0, built there if missing). Each mesh is
also turned so that its up becomes +x, -x, +y, -y, +z, -z (rotations by 90 degrees), and the
rule's answer is compared with the true up: right, right axis but wrong sign, or wrong. Shapes
with no natural up (pyvista's nut and sphere) are listed with what the rule gives.
Writes bench/results/up_axis.json ({meshes: [{name, up, detected: {orientation: axis}, right,
axis_only, wrong}], totals, seconds_per_mesh, machine}; bench/_harness.py).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bench._harness import Bench
from bench._tables import rows_table

if TYPE_CHECKING:
    import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NAMES = {(0, 1): "+x", (0, -1): "-x", (1, 1): "+y", (1, -1): "-y", (2, 1): "+z", (2, -1): "-z"}


def axis_name(v) -> str:
    import numpy as np

    k = int(np.argmax(np.abs(v)))
    return NAMES[(k, int(np.sign(v[k])))]


def rotation_to(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """A rotation by multiples of 90 degrees taking axis vector src to axis vector dst."""
    import numpy as np

    if np.allclose(src, dst):
        return np.eye(3)
    if np.allclose(src, -dst):  # half turn about an axis perpendicular to both
        k = int(np.argmin(np.abs(src)))
        a = np.eye(3)[k]
        return 2 * np.outer(a, a) - np.eye(3)
    a = np.cross(src, dst)  # quarter turn about src x dst
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + K + K @ K


def main() -> None:
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--creatures", type=int, default=64)
    ap.add_argument("--creatures-dir", default=str(ROOT / ".cache/datasets/creatures_n64_s0"))
    args = ap.parse_args()
    bench = Bench("up_axis")

    from ngc_gen.data.procedural.creatures import build_creatures
    from ngc_gen.data.mesh.io import load_mesh
    from ngc_gen.viz.camera import detect_up

    meshes = [("ant", "pyvista:ant.ply", "+y"), ("airplane", "pyvista:airplane.ply", "+z")]
    folder = Path(args.creatures_dir)
    if len(list(folder.glob("creature_*.ply"))) < args.creatures:
        build_creatures(folder, n=64, seed=0)
    meshes += [(p.stem, str(p), "+z") for p in sorted(folder.glob("creature_*.ply"))
               [:args.creatures]]
    others = [("nut", "pyvista:nut.ply"), ("sphere", "pyvista:sphere.ply")]
    axes = {n: np.eye(3)[k] * s for (k, s), n in NAMES.items()}

    rows, seconds = [], []
    for name, path, up in meshes:
        V = np.asarray(load_mesh(path).vertices)
        row = {"name": name, "up": up, "detected": {}, "right": 0, "axis_only": 0, "wrong": 0}
        for target, t in axes.items():
            R = rotation_to(axes[up], t)
            t0 = time.perf_counter()
            got = axis_name(detect_up(V @ R.T))
            seconds.append(time.perf_counter() - t0)
            row["detected"][target] = got
            kind = ("right" if got == target else
                    "axis_only" if got[1] == target[1] else "wrong")
            row[kind] += 1
        rows.append(row)
        print(f"{name:14s} true {up}: " + " ".join(f"{k}->{v}" for k, v in row["detected"].items())
              + f"   right {row['right']}/6")
    for name, path in others:
        got = axis_name(detect_up(np.asarray(load_mesh(path).vertices)))
        rows.append({"name": name, "up": None, "detected": {"as shipped": got}})
        print(f"{name:14s} no natural up: {got}")
    known = [r for r in rows if r["up"]]
    totals = {k: sum(r[k] for r in known) for k in ("right", "axis_only", "wrong")}
    totals["orientations"] = 6 * len(known)
    print(f"\n{totals['right']}/{totals['orientations']} right, {totals['axis_only']} with the "
          f"right axis but the wrong sign, {totals['wrong']} wrong; "
          f"{1e3 * np.mean(seconds):.0f} ms per mesh")
    path = bench.write({"meshes": rows, "totals": totals,
                        "seconds_per_mesh": float(np.mean(seconds))})
    print(f"wrote {path}")


# ---- the table (bench/README.md) and the headline (README.md), from the result ----------
def table(r: dict) -> str:
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


def headline(r):
    t = r["totals"]
    return f"up axis right in {t['right']} of {t['orientations']} orientations"


if __name__ == "__main__":
    main()
