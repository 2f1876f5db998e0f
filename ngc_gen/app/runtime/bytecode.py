"""`python -m ngc_gen.app.runtime.bytecode`: byte-compile what the commands import, once, at setup.

Where PYTHONDONTWRITEBYTECODE=1 is set (common in containers) and packages were installed with
`pip --no-compile`, no .pyc is ever written, so every command compiles torch, Lightning,
trimesh and the project from source again (the Makefile's setup runs this module; bench/cli.py
measures what it adds to setup and saves per command). Importing the runners with bytecode
writing switched on compiles exactly the modules a command loads (not every module of every
package, which `compileall` would do at several times the cost); a tiny extraction compiles the
numba kernels into their cache, which the first command would otherwise do.
"""
from __future__ import annotations

import compileall
import importlib
import importlib.util
import sys
import time
from pathlib import Path

# beside the runners of the stage registry (train.py's stages, edit.py, sample.py): what their
# work imports later (torch, Lightning, trimesh, scipy, hydra, viser)
RUNNERS = ("ngc_gen.app.stages.sample_condition",
           "ngc_gen.edit.program", "ngc_gen.shape", "ngc_gen.extract.extractor", "ngc_gen.viz",
           "lightning.pytorch", "ngc_gen.app.editor.server", "pyvista.plotting")
# packages whose modules load late (numba's while it compiles or loads a cached kernel,
# pyvista's and VTK's when a picture is drawn, Hydra's plugins while it composes): compiled
# whole, as they are small next to torch (~1,100 files); found without importing them
LATE_PACKAGES = ("numba", "pyvista", "vtkmodules", "hydra", "hydra_plugins", "scooby")


def warm_kernels() -> None:
    """Compile the project's numba kernels into their on-disk cache (`cache=True`): a tiny
    extraction runs the relative-coordinate, sparse-refinement, settling and marching kernels
    with the types real runs use. Otherwise the first edit or fit after an install (or after
    a change of a kernel's source) compiles them, ~20 s on 2 busy cores."""
    import torch

    from ngc_gen.extract import extract_mesh, per_gc_rows
    from ngc_gen.geometry import GeneralizedCylinder

    gc = GeneralizedCylinder.from_dict({
        "name": "warm", "curve": {"type": "bezier", "points": [[-0.4, 0, 0], [0, 0.1, 0],
                                                               [0.4, 0, 0]]},
        "keys": [{"t": 0.0, "radii": [0.2, 0.15]}], "caps": [0.1, 0.1]})

    def sdf(j, rel):
        return (torch.linalg.norm(rel.double(), dim=1) - 0.3).float()

    extract_mesh([gc], per_gc_rows(sdf), 128)  # every level of the refinement runs


def main() -> int:
    sys.dont_write_bytecode = False  # the point of this module, whatever the environment says
    t0 = time.perf_counter()
    missing = []
    from ngc_gen.app.stages.registry import COMMANDS, STAGES

    stages = [s.runner.split(":")[0] for s in (*STAGES.values(), *COMMANDS.values())]
    for name in (*stages, *RUNNERS):
        try:
            importlib.import_module(name)
        except ImportError as e:  # an optional extra (viser) not installed: compile the rest
            missing.append(f"{name} ({e.name or e})")
    warm_kernels()
    for name in LATE_PACKAGES:
        spec = importlib.util.find_spec(name)
        for folder in (spec.submodule_search_locations or []) if spec else []:
            compileall.compile_dir(Path(folder), quiet=1, workers=0)
    n = sum(1 for m in sys.modules.values() if getattr(m, "__cached__", None))
    print(f"bytecode: {n} imported modules and {', '.join(LATE_PACKAGES)} compiled or current "
          f"in {time.perf_counter() - t0:.1f} s"
          + (f"; not importable: {', '.join(missing)}" if missing else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
