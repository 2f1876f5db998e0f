"""Data layer: meshes, GC annotations, SDF sampling and per-shape caches (DESIGN.md section 1).

The public entry points are re-exported here; dataset builders and DataModules live in their
own modules of this package.
"""

import importlib

# name -> module; loaded on first use (PEP 562) so that a light module of this package (errors,
# mesh_folder) does not pull in trimesh and torch: train.py checks a bad data.path in a second
_HOMES = {"Annotation": "annotations", "annotation_from_dict": "annotations",
          "load_annotation": "annotations", "save_annotation": "annotations",
          "AutoGCSettings": "auto_gc", "auto_annotation": "auto_gc", "auto_gc": "auto_gc",
          "auto_gcs": "auto_gc", "DataError": "errors", "load_mesh": "mesh_io",
          "normalize": "mesh_io", "resolve_mesh_path": "mesh_io", "PreparedShape": "prepare",
          "PrepareSettings": "prepare", "load_prepared": "prepare", "prepare_shape": "prepare",
          "signed_distance": "sdf"}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)


__all__ = [
    "Annotation", "AutoGCSettings", "DataError", "PrepareSettings", "PreparedShape", "annotation_from_dict",
    "auto_annotation", "auto_gc", "auto_gcs", "load_annotation", "load_mesh", "load_prepared", "normalize",
    "prepare_shape", "resolve_mesh_path", "save_annotation", "signed_distance",
]
