"""Data layer: meshes, GC annotations, SDF sampling and per-shape caches (DESIGN.md section 1).

The public entry points are re-exported here; dataset builders and DataModules live in their
own modules of this package.
"""

from ngc_gen.data.annotations import Annotation, annotation_from_dict, load_annotation, save_annotation
from ngc_gen.data.auto_gc import AutoGCSettings, auto_annotation, auto_gc, auto_gcs
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh_io import load_mesh, normalize, resolve_mesh_path
from ngc_gen.data.prepare import PreparedShape, PrepareSettings, load_prepared, prepare_shape
from ngc_gen.data.sdf import signed_distance

__all__ = [
    "Annotation", "AutoGCSettings", "DataError", "PrepareSettings", "PreparedShape", "annotation_from_dict",
    "auto_annotation", "auto_gc", "auto_gcs", "load_annotation", "load_mesh", "load_prepared", "normalize",
    "prepare_shape", "resolve_mesh_path", "save_annotation", "signed_distance",
]
