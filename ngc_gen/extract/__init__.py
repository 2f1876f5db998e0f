"""Mesh extraction: sparse multi-level (default) or reference grids, batched network rows, a
per-GC value cache for incremental edits, bricked marching cubes.

Takes the network as `rows_fn(gc_index (M,), rel (M, 3)) -> (M,)`; imports only
ngc_gen.geometry (docs/architecture.md, 3 and 7).

Names are loaded on first use (PEP 562), so `ngc_gen.extract.budget` (the memory a resolution
needs) imports without torch: the entry points refuse a resolution that does not fit before
the heavy modules load."""
from __future__ import annotations

import importlib

_HOME = {
    **dict.fromkeys(["METHODS", "ExtractionResult", "extract_mesh"], "extractor"),
    "Grid": "grid",
    **dict.fromkeys(["empty_mesh", "marching_cubes_grid", "marching_cubes_mesh"], "marching"),
    **dict.fromkeys(["RowsFn", "SdfFn", "per_gc_rows"], "rows"),
    "SparseSettings": "sparse",
    "FieldCache": "store",
    **dict.fromkeys(["GridTooLarge", "check_resolution", "largest_resolution"], "budget"),
}
__all__ = sorted(_HOME)


def __getattr__(name: str):
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOME[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_HOME))
