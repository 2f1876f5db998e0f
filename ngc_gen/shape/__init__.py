"""One object for "a shape we can evaluate": GCs + per-GC codes + the NGC decoder
(docs/architecture.md). Built from a fit checkpoint, a generated sample, a mix or a
reconstruction; every caller gets SDF values and meshes through it (`Shape.sdf`,
`Shape.mesh`), and edits through `Shape.edited(program)` / `Shape.with_part(...)`."""
from .features import PartFeatures, blend_features
from .load import autodecoder_mesh, load_shapes, recorded_gcs, shapes_from_autodecoder
from .shape import Shape

__all__ = ["PartFeatures", "Shape", "autodecoder_mesh", "blend_features", "load_shapes",
           "recorded_gcs", "shapes_from_autodecoder"]
