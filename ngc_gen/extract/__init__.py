"""Mesh extraction: sparse multi-level (default) or reference grids, batched network rows, a
per-GC value cache for incremental edits, bricked marching cubes.

Takes the network as `rows_fn(gc_index (M,), rel (M, 3)) -> (M,)`; imports only
ngc_gen.geometry (docs/architecture.md, 3 and 7)."""
from .extractor import METHODS, ExtractionResult, extract_mesh
from .grid import Grid
from .marching import empty_mesh, marching_cubes_grid, marching_cubes_mesh
from .rows import RowsFn, SdfFn, per_gc_rows
from .sparse import SparseSettings
from .store import FieldCache

__all__ = ["METHODS", "ExtractionResult", "FieldCache", "Grid", "RowsFn", "SdfFn",
           "SparseSettings", "empty_mesh", "extract_mesh", "marching_cubes_grid",
           "marching_cubes_mesh", "per_gc_rows"]
