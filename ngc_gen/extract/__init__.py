"""Mesh extraction: grid, GC prefilter, optional coarse-to-fine refinement, marching cubes.

Takes the network as a callable `sdf_fn(gc_index, rel) -> sdf`; imports only ngc_gen.geometry
(DESIGN.md sections 1 and 3)."""
from .evaluate import MinField, SdfFn
from .extractor import ExtractionResult, extract_mesh
from .grid import Grid
from .marching import empty_mesh, marching_cubes_grid, marching_cubes_mesh
from .refine import Refinement
from .smooth_union import extract_smooth_union

__all__ = ["ExtractionResult", "Grid", "MinField", "Refinement", "SdfFn", "empty_mesh",
           "extract_mesh", "extract_smooth_union", "marching_cubes_grid", "marching_cubes_mesh"]
