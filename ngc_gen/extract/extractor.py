"""`extract_mesh`: the NGC surface of a set of GCs and a per-GC SDF as a triangle mesh (paper 4.1).

Grid over [-bound, bound]^3 with `resolution` points per axis; a grid point outside every GC gets
a positive background value; a point inside several GCs takes the minimum of their SDFs (or their
smooth minimum of width `smooth`, folded in GC order), or with `blend` > 0 their blend weighted by
where the point lies in each GC (`ngc_gen.geometry.union`); marching cubes at level 0. Three methods
compute the same values wherever the mesh needs them:

* "sparse" (default): coarse-to-fine over blocks that may hold the surface, marching cubes only
  over the cells that can (`ngc_gen.extract.sparse`); optionally incremental with a `FieldCache`;
* "prefiltered": every grid point inside a GC (bounding-box index ranges, then the exact inside
  test): the reference for sparse;
* "dense": every grid point of the box for every GC, masked afterwards: the reference for the
  prefilter (R^3 x len(gcs) network evaluations).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Hashable, Sequence

import numpy as np
import trimesh

from ngc_gen.geometry import GeneralizedCylinder

from .budget import check_resolution
from .dense import evaluate_grid
from .grid import Grid
from .marching import marching_cubes_mesh
from .rows import RowsFn, new_stats
from .sparse import SparseSettings, extract_sparse
from .store import FieldCache, PointStore

METHODS = ("sparse", "prefiltered", "dense")


@dataclass
class ExtractionResult:
    """mesh: the level-0 surface (empty if the field never crosses 0); stats: counts and
    seconds (see `extract_mesh`); values: the (R, R, R) float32 grid if `keep_values` (for
    "sparse", NaN where the field was not needed)."""

    mesh: trimesh.Trimesh
    stats: dict = field(default_factory=dict)
    values: np.ndarray | None = None


def gc_list(gcs) -> list[GeneralizedCylinder]:
    gcs = list(gcs)
    for i, gc in enumerate(gcs):
        if not isinstance(gc, GeneralizedCylinder):
            raise TypeError(f"gcs[{i}] must be a GeneralizedCylinder, got {type(gc).__name__}")
    return gcs


def extract_mesh(gcs: Sequence[GeneralizedCylinder], rows_fn: RowsFn, resolution: int = 256,
                 bound: float = 1.0, method: str = "sparse", smooth: float = 0.0,
                 blend: float = 0.0, blend_k: float = 0.0, cache: FieldCache | None = None,
                 gc_keys: Sequence[Hashable] | None = None, *,
                 chunk: int = 65536, background: float | None = None, fixed_batch: bool = False,
                 device=None, keep_values: bool = False, settings: SparseSettings | None = None,
                 progress: bool | None = None, slab_points: int = 1 << 18) -> ExtractionResult:
    """Extract the NGC surface.

    gcs: the shape's GCs. rows_fn(gc_index (M,) int64, rel (M, 3) float32) -> (M,) values: one
      batched call across GCs (wrap the network with its codes and torch.inference_mode yourself,
      e.g. `ngc_gen.shape.Shape.rows`; `per_gc_rows` adapts an sdf_fn(j, rel)).
    resolution, bound: grid points per axis over [-bound, bound]^3 (paper: 256 over [-1, 1]).
    method: "sparse" | "prefiltered" | "dense" (module docstring).
    smooth: 0 takes the hard minimum over the GCs containing a point; k > 0 their polynomial
      smooth minimum of width k (`ngc_gen.geometry.smooth`), a smooth union where parts overlap.
    blend, blend_k: the blended union's width in (0, 1] and softness (`ngc_gen.geometry.union`;
      blend 0: the min / smooth min above; with a blend, smooth must be 0).
    cache, gc_keys: with a `FieldCache`, per-GC values are kept under gc_keys[i] (hashable; the
      caller's key for GC i's parameters and code) and only GCs with new keys are evaluated
      (sparse only); the mesh equals a full re-extraction.
    chunk: rows per rows_fn call (bounds memory); no call is padded unless `fixed_batch`
      (exactness tests: every call exactly `chunk` rows of one GC, so a row's value cannot
      depend on its batch). device: where rel and gc_index go (CPU if None).
    background: value for points outside every GC; default one grid spacing, so marching cubes
      interpolates like a distance field where the surface meets a GC boundary.
    settings: sparse refinement (coarse step, Lipschitz margin). keep_values: return the grid.
    progress: tqdm bar for the reference paths (None: only on a terminal, after 1 s).
    A resolution whose grid would not fit in the memory available is refused first
    (`budget.GridTooLarge`, naming the largest that fits).
    slab_points: grid points whose coordinates are built at once (reference paths).

    stats: n_grid_points (R^3), n_network_evals (rows sent to rows_fn, padding excluded),
    n_network_rows (including padding), n_network_calls, n_relative (relative coordinates
    computed), n_covered (points of the final field inside some GC), n_faces, n_vertices,
    seconds (total) and seconds_network / _geometry / _marching; sparse also coarse_step,
    levels (per level: step, blocks, kept, network_evals, seconds; the last level also new_points
    and settled, new points of its blocks settled without evaluation), n_active_cells,
    n_corner_points, completion_network_evals, cache_hits, cache_misses.
    """
    t_start = time.perf_counter()
    gcs = gc_list(gcs)
    smooth, blend = float(smooth), float(blend)
    _check_arguments(gcs, resolution, method, smooth, cache, gc_keys, keep_values, blend)
    grid = Grid(int(resolution), float(bound))
    background = grid.spacing if background is None else float(background)
    if not (np.isfinite(background) and background > 0):
        raise ValueError(f"background must be a positive finite value, got {background!r}")
    stats = new_stats()
    queue_args = dict(rows_fn=rows_fn, chunk=chunk, fixed_batch=fixed_batch, device=device)

    values = None
    if method == "sparse":
        stores, hits = [PointStore() for _ in gcs], 0
        if cache is not None:
            got = [cache.get(k, grid.resolution, grid.bound) for k in gc_keys]
            stores, hits = [s for s, _ in got], sum(h for _, h in got)
        stats.update(cache_hits=hits, cache_misses=len(gcs) - hits)
        mesh, values = extract_sparse(gcs, grid, stores, queue_args, stats, smooth, background,
                                      settings or SparseSettings.from_yaml(), keep_values, blend, blend_k)
    else:
        flat = evaluate_grid(gcs, grid, queue_args, stats, smooth, method == "prefiltered",
                             slab_points, progress, blend, blend_k)
        covered = np.isfinite(flat)
        stats["n_covered"] = int(covered.sum())
        flat[~covered] = background
        values = flat.reshape((grid.resolution,) * 3)
        t0 = time.perf_counter()
        mesh = marching_cubes_mesh(values, grid)
        stats["seconds_marching"] = time.perf_counter() - t0
    stats.update(n_grid_points=grid.n_points, n_gcs=len(gcs), resolution=grid.resolution,
                 bound=grid.bound, background=background, method=method, smooth=smooth,
                 blend=blend, blend_k=blend_k if blend else 0.0, fixed_batch=bool(fixed_batch),
                 n_faces=len(mesh.faces), n_vertices=len(mesh.vertices))
    stats["seconds"] = time.perf_counter() - t_start
    return ExtractionResult(mesh, stats, values if keep_values else None)


def _check_arguments(gcs, resolution, method, smooth, cache, gc_keys, keep_values,
                     blend=0.0) -> None:
    """ValueError for an argument of `extract_mesh` it cannot work with; `GridTooLarge` for a
    resolution that does not fit in memory (checked before any grid is allocated)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if not smooth >= 0.0:
        raise ValueError(f"smooth must be >= 0 (0: hard minimum; k > 0: smooth-min width), "
                         f"got {smooth!r}")
    if blend:
        from ngc_gen.geometry.union import check_width

        check_width(blend)
        if smooth:
            raise ValueError(f"pass a smooth-min width or a blend width, not both (smooth="
                             f"{smooth}, blend={blend})")
    check_resolution(int(resolution), method, keep_values)
    if cache is not None and method != "sparse":
        raise ValueError(f"a FieldCache works with method='sparse', not {method!r}")
    if (cache is None) != (gc_keys is None):
        raise ValueError("pass cache and gc_keys together (one key per GC)")
    if gc_keys is not None and len(gc_keys) != len(gcs):
        raise ValueError(f"gc_keys must hold one key per GC: {len(gc_keys)} keys, {len(gcs)} GCs")
