"""Blender's glTF importer as a client check: import a GLB headless (`blender -b`), read back
its armature, binding, actions and shape keys, and compare Blender's evaluated mesh at clip times
with this package's own playback of the file (`Playback`)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from .playback import Playback

SCRIPT = Path(__file__).with_name("blender_script.py")


def blender_available() -> bool:
    return shutil.which("blender") is not None


def blender_import(path: str | os.PathLike, times: list[float], timeout: float = 300.0) -> dict:
    """{info (what Blender made), vertices: [(V, 3) per time]} of the GLB in Blender."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "blender.npz"
        run = subprocess.run(["blender", "-b", "--factory-startup", "--python", str(SCRIPT), "--",
                              os.fspath(path), str(out), ",".join(repr(float(t)) for t in times)],
                             capture_output=True, text=True, timeout=timeout)
        if not out.is_file():
            raise RuntimeError(f"Blender could not import {path}: "
                               f"{(run.stderr or run.stdout)[-400:]}")
        d = np.load(out)
        return {"info": json.loads(str(d["info"])),
                "vertices": [d[f"v{i}"] for i in range(len(d["times"]))]}


def blender_check(path: str | os.PathLike, gc_names: list[str], joints_per_gc: int,
                  times: list[float], tol: float = 1e-4) -> dict:
    """What Blender made of the file against what it should be: one armature whose bones are
    `<gc>_<k>` for every GC, the mesh bound to it, an action, one shape key per morph target,
    and at each time the evaluated mesh within `tol` x the bounding-box diagonal of the file's
    own skinning + morph result. Returns the numbers and `blender_ok`."""
    got = blender_import(path, times)
    info, p = got["info"], Playback(path)
    want = [f"{g}_{k}" for g in gc_names for k in range(joints_per_gc)]
    diag = float(np.linalg.norm(np.ptp(p.vertices(), 0)))
    errors = []
    for t, v in zip(times, got["vertices"]):
        mine = p.vertices(t)
        errors.append(float(np.abs(mine - v).max()) / diag if v.shape == mine.shape
                      else float("inf"))
    n_targets = 0 if p.targets is None else len(p.targets)
    checks = {"one_armature": info["armatures"] == 1,
              "joint_names": sorted(info["bones"]) == sorted(want),
              "bound": bool(info["bound"]), "action": len(info["actions"]) >= 1,
              "shape_keys": len(info["shape_keys"]) == n_targets,
              "pose": max(errors) <= tol}
    return {"blender_ok": all(checks.values()), "checks": checks, "times": list(times),
            "max_error_over_diag": errors, "bones": len(info["bones"]),
            "shape_keys": len(info["shape_keys"]), "actions": info["actions"]}
