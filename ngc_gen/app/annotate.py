"""Stage `annotate`: automatic GCs for every mesh of a dataset (README "Automatic GCs").

    python train.py stage=annotate data=folder data.path=DIR [annotate.write_beside=true]

Per mesh: `<name>.yaml` (an editable annotation; `prepare`/`fit` read it when it lies beside the
mesh) and `<name>_gcs.png` (the GCs drawn over the mesh) in the run directory, and with
`annotate.write_beside=true` beside the mesh too. A YAML beside a mesh that this stage did not
write (a hand annotation) is never overwritten. Prints a table: mesh, GCs, coverage, seconds,
and each mesh's GC names (what edit programs refer to).
"""
from __future__ import annotations

import time
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig, OmegaConf

from ngc_gen.data.annotations import Annotation
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
from ngc_gen.data.autogc.coverage import coverage_stats
from ngc_gen.data.mesh.io import load_mesh, normalize
from ngc_gen.data.mesh.sampling import sample_surface

from .training import start_run

HEADER = "# written by `train.py stage=annotate` (automatic GCs); edit freely, or delete to redo\n"
COVERAGE_SAMPLES = 50_000


def _meshes(dataset) -> list[tuple[str, str, float | None]]:
    """(name, mesh file or resource, bound) of every shape of the dataset."""
    if hasattr(dataset, "mesh_files"):
        return [(p.stem, str(p), dataset.bound) for p in dataset.mesh_files()]
    return [(a.name, a.mesh, a.bound) for a in dataset.shapes()]


def _write_yaml(ann: Annotation, path: Path) -> None:
    atomic_write_text(path, HEADER + ann.to_yaml(relative_to=path.parent.resolve()))


def _ours(path: Path) -> bool:
    """True if there is no file at path or this stage wrote it."""
    return not path.exists() or path.read_text(encoding="utf-8", errors="replace").startswith(HEADER)


def _picture(ann: Annotation, path: Path, up="auto") -> Path | None:
    """The GCs over the mesh, and alone with their names (`up`: `viz.up`)."""
    import trimesh

    from ngc_gen.viz import gc_labels, gcs_surface, render_grid, render_or_warn

    mesh, _, _ = normalize(load_mesh(ann.mesh_path), ann.bound)
    shell = gcs_surface(ann.gcs)
    return render_or_warn(render_grid, path,
                          [[(mesh, shell), (trimesh.Trimesh(shell.vertices, shell.faces), None,
                                            gc_labels(ann.gcs))]],
                          col_titles=[f"{ann.name}: {len(ann.gcs)} GCs over the mesh",
                                      "the GCs by name"], frame="row", up=up)


def run_annotate(cfg: DictConfig) -> list[dict]:
    run_dir = start_run(cfg)
    settings = AutoGCSettings.from_config(OmegaConf.to_container(cfg.annotate, resolve=True))
    beside = bool(cfg.annotate.get("write_beside", False))
    dataset = hydra.utils.instantiate(cfg.data)
    rows = []
    for name, mesh, bound in _meshes(dataset):
        t0 = time.perf_counter()
        ann = auto_annotation(mesh, name=name, bound=bound, settings=settings)
        seconds = time.perf_counter() - t0
        normalized, _, _ = normalize(load_mesh(mesh), bound)
        points, _ = sample_surface(normalized.vertices, normalized.faces, COVERAGE_SAMPLES,
                                   np.random.default_rng(settings.seed + 1))
        stats = coverage_stats(ann.gcs, points)
        _write_yaml(ann, run_dir / f"{name}.yaml")
        _picture(ann, run_dir / f"{name}_gcs.png", cfg.viz.up)
        wrote = []
        if beside and not Path(mesh).exists():
            wrote.append("not beside (a resource)")
        elif beside:
            target = Path(mesh).with_suffix(".yaml")
            if _ours(target):
                _write_yaml(ann, target)
                _picture(ann, target.with_name(f"{name}_gcs.png"), cfg.viz.up)
                wrote.append(f"beside: {target}")
            else:
                wrote.append(f"kept the hand annotation {target}")
        rows.append({"mesh": name, "n_gcs": len(ann.gcs), "coverage": stats["coverage"],
                     "overlap": stats["overlap"], "seconds": seconds, "gc_names": ann.gc_names,
                     "notes": wrote})
    print_table(rows, settings)
    print(f"run directory: {run_dir}")
    return rows


def print_table(rows: list[dict], settings: AutoGCSettings) -> None:
    print(f"\n{'mesh':24s} {'GCs':>4s} {'coverage':>9s} {'seconds':>8s}   method {settings.method}")
    for r in rows:
        print(f"{r['mesh']:24s} {r['n_gcs']:4d} {100 * r['coverage']:8.3f}% {r['seconds']:8.2f}")
    for r in rows:
        print(f"{r['mesh']}: GCs {', '.join(r['gc_names'])}" + "".join(f"; {n}" for n in r["notes"]))
