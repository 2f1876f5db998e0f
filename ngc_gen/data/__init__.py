"""Data layer: meshes, GC annotations, SDF sampling and per-shape caches (docs/architecture.md).

The public entry points are re-exported here. Rooms: ``mesh/`` (I/O, proxy, SDF, samplers),
``procedural/`` (the creatures), ``autogc/`` (automatic GCs); annotations, preparation, datasets
and the DataModule sit at the top.
"""

import importlib

# name -> module; loaded on first use (PEP 562) so that a light module of this package (errors,
# mesh_folder) does not pull in trimesh and torch: train.py checks a bad data.path in a second
_HOMES = {"Annotation": "annotations", "annotation_from_dict": "annotations",
          "load_annotation": "annotations", "save_annotation": "annotations",
          "AutoGCSettings": "autogc.auto", "auto_annotation": "autogc.auto",
          "auto_gcs": "autogc.auto", "DataError": "errors", "load_mesh": "mesh.io",
          "normalize": "mesh.io", "resolve_mesh_path": "mesh.io", "PreparedShape": "prepare",
          "PrepareSettings": "prepare", "load_prepared": "prepare", "prepare_shape": "prepare",
          "signed_distance": "mesh.sdf"}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)


__all__ = sorted(_HOMES)
