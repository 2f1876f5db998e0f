"""Editing: pure GC -> GC edits, handle deformation, part mixing, edit programs (DESIGN.md
section 4).

The neural codes never change: an edit only changes GCs (and part mixing only blends features),
so a fitted shape is deformed with no re-training. `ops`, `handles`, `blend` and `program` use
only ngc_gen.geometry; `mixing` builds extraction fields (ngc_gen.extract). edit.py's runner
(reads checkpoints, writes files) is ngc_gen.app.edit.
"""
from .blend import (BLENDS, blend_features, blend_weight, constant, linear, smooth_min,
                    smooth_min_all, smoothstep, truncated_linear)
from .errors import EditError
from .handles import HandleSolve, bend_to, deform_by_handles, hermite_of_length, kabsch
from .mixing import PartMix, extract_smooth_union, mixed_sdf_fn
from .ops import (OPS, apply, compose, local_motion, move_points, rigid, rotate, scale_radii,
                  stretch, stretch_map, translate, twist, twist_ramp)
from .program import EditProgram, apply_program

__all__ = ["BLENDS", "EditError", "EditProgram", "HandleSolve", "OPS", "PartMix", "apply",
           "apply_program", "bend_to", "blend_features", "blend_weight", "compose", "constant",
           "deform_by_handles", "extract_smooth_union", "hermite_of_length", "kabsch", "linear",
           "local_motion", "mixed_sdf_fn", "move_points", "rigid", "rotate", "scale_radii",
           "smooth_min", "smooth_min_all", "smoothstep", "stretch", "stretch_map", "translate",
           "truncated_linear", "twist", "twist_ramp"]
