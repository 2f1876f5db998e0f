"""`extract_mesh`: the NGC surface of a set of GCs and a per-GC SDF as a triangle mesh (paper 4.1).

Grid over [-bound, bound]^3 with `resolution` points per axis; a grid point outside every GC gets
a positive background value; a point inside several GCs takes the minimum of their SDFs;
marching cubes at level 0. The network (`sdf_fn`) is evaluated only at grid points inside a GC
(bounding-box index ranges, then the exact inside test on the relative coordinates), unless
`prefilter=False`, which evaluates it densely and must give the identical grid.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import torch
import trimesh
from tqdm.auto import tqdm

from ngc_gen.geometry import GeneralizedCylinder

from .evaluate import MinField, SdfFn, as_numpy_grid, fill_background, gc_list
from .grid import Grid
from .marching import marching_cubes_mesh
from .refine import (Refinement, block_marks, coarse_indices, coarse_point_mask, fill_interpolated,
                     fine_mask)


@dataclass
class ExtractionResult:
    """mesh: the level-0 surface (empty if the field never crosses 0); stats: counts and
    seconds (see `extract_mesh`); values: the (R, R, R) float32 grid if `keep_values`."""

    mesh: trimesh.Trimesh
    stats: dict = field(default_factory=dict)
    values: np.ndarray | None = None


def extract_mesh(gcs: list[GeneralizedCylinder], sdf_fn: SdfFn, resolution: int = 256,
                 bound: float = 1.0, *, chunk: int = 65536, background: float | None = None,
                 prefilter: bool = True, refine: bool | Refinement = False,
                 fixed_batch: bool | None = None, device=None, keep_values: bool = False,
                 progress: bool | None = None, slab_points: int = 1 << 18) -> ExtractionResult:
    """Extract the NGC surface.

    gcs: the shape's GCs. sdf_fn(gc_index, rel) -> sdf: rel (M, 3) float32 [u, a, b] on `device`
      (CPU if None), returns (M,) values (any device; wrap the network with its code and
      torch.no_grad yourself).
    resolution, bound: grid points per axis over [-bound, bound]^3 (paper: 256 over [-1, 1]).
    chunk: rows per sdf_fn call. fixed_batch: pad every call to exactly `chunk` rows, so a
      point's value never depends on its batch (bit-exact prefilter for real networks); costs
      at most one padded chunk per GC (and pass). None: on for the exact path, off with `refine`
      (approximate anyway, and its small coarse pass would be mostly padding).
    background: value for points outside every GC; default one grid spacing, so marching cubes
      interpolates like a distance field where the surface meets a GC boundary.
    prefilter: True evaluates only points inside a GC; False evaluates every grid point for every
      GC and masks afterwards (the exactness reference; R^3 * len(gcs) evaluations).
    refine: False (exact) or True / Refinement(factor, margin, dilate): coarse-to-fine, fewer
      evaluations, APPROXIMATE for learned SDFs (see ngc_gen.extract.refine).
    progress: tqdm bar (None: only on a terminal, shown after 1 s); keep_values: return the grid.
    slab_points: grid points whose coordinates are built at once (memory bound).

    stats: n_grid_points (R^3), n_network_evals (points sent to sdf_fn, padding excluded),
    n_network_rows (including padding), n_network_calls, n_relative (relative coordinates
    computed), n_inside (points inside a GC, counted once per GC), n_covered (evaluated points
    inside some GC), n_faces, n_vertices, seconds (total) and seconds_network / _geometry /
    _marching; with refinement also n_coarse_evals and n_fine_evals (network evaluations of each pass).
    """
    t_start = time.perf_counter()
    gcs = gc_list(gcs)
    grid = Grid(int(resolution), float(bound))
    background = grid.spacing if background is None else float(background)
    if not (np.isfinite(background) and background > 0):
        raise ValueError(f"background must be a positive finite value, got {background!r}")
    ref = Refinement() if refine is True else (refine or None)
    if ref is not None and not isinstance(ref, Refinement):
        raise TypeError(f"refine must be a bool or a Refinement, got {type(refine).__name__}")
    if fixed_batch is None:
        fixed_batch = ref is None
    field_ = MinField(grid, sdf_fn, chunk=chunk, fixed_batch=fixed_batch, device=device,
                      slab_points=slab_points, prefilter=prefilter)
    bar_kw = dict(disable=None if progress is None else not progress, delay=1.0, unit="slab",
                  leave=False)

    if ref is None:
        _run(field_, gcs, grid.full(), None, "extract", bar_kw)
        n_covered = fill_background(field_.values, background)
        values = as_numpy_grid(field_.values, grid)
    else:
        values, n_covered = _refined(field_, gcs, grid, ref, background, bar_kw)

    t0 = time.perf_counter()
    mesh = marching_cubes_mesh(values, grid)
    stats = dict(field_.stats)
    stats.update(n_grid_points=grid.n_points, n_covered=n_covered, n_gcs=len(gcs),
                 resolution=grid.resolution, bound=grid.bound, background=background,
                 prefilter=bool(prefilter), refine=ref is not None, fixed_batch=fixed_batch,
                 n_faces=len(mesh.faces), n_vertices=len(mesh.vertices),
                 seconds_marching=time.perf_counter() - t0)
    stats["seconds"] = time.perf_counter() - t_start
    return ExtractionResult(mesh, stats, values if keep_values else None)


def _run(field_: MinField, gcs, lattice, mask, desc: str, bar_kw: dict) -> None:
    with tqdm(total=field_.count_slabs(gcs, lattice), desc=desc, **bar_kw) as bar:
        for i, gc in enumerate(gcs):
            field_.add_gc(i, gc, lattice, mask=mask, bar=bar)


def _refined(field_: MinField, gcs, grid: Grid, ref: Refinement, background: float,
             bar_kw: dict) -> tuple[np.ndarray, int]:
    R = grid.resolution
    c = coarse_indices(R, ref.factor)
    _run(field_, gcs, (c, c, c), None, "extract coarse", bar_kw)
    n_coarse = field_.stats["n_network_evals"]
    values = as_numpy_grid(field_.values, grid)          # a view: writes go to field_.values
    coarse = values[np.ix_(c, c, c)].copy()
    coarse_cov = np.isfinite(coarse)
    coarse[~coarse_cov] = background
    marks = block_marks(coarse, coarse_cov, c, grid, ref)
    refined = fine_mask(marks, c, R)
    on_coarse = coarse_point_mask(c, R)
    todo = torch.from_numpy((refined & ~on_coarse).reshape(-1))
    _run(field_, gcs, grid.full(), todo, "extract fine", bar_kw)
    evaluated = refined | on_coarse
    del refined, on_coarse
    # unevaluated points are still +inf too: interpolate those, then background the rest
    fill_interpolated(values, evaluated, coarse, c)
    n_covered = fill_background(field_.values, background)
    field_.stats.update(n_coarse_evals=n_coarse,
                        n_fine_evals=field_.stats["n_network_evals"] - n_coarse)
    return values, n_covered
