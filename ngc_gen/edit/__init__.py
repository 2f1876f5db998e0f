"""Editing: pure GC -> GC edits, handle deformation, part mixing, edit programs (DESIGN.md
section 4).

The neural codes never change: an edit only changes GCs (and part mixing only blends features),
so a fitted shape is deformed with no re-training. `ops`, `handles`, `blend` and `program` use
only ngc_gen.geometry and the part-mixing rule of ngc_gen.shape; a program applies to a
`ngc_gen.shape.Shape` (`Shape.edited`). Runners (edit.py) live in ngc_gen.app.
"""
from .blend import (BLEND_PARAMS, BLENDS, blend_features, blend_weight, constant, linear,
                    mix_weight, smoothstep, truncated_linear)
from .errors import EditError
from .handles import HandleSolve, bend_to, deform_by_handles, hermite_of_length, kabsch
from .ops import (OPS, apply, compose, local_motion, move_points, rigid, rotate, scale_radii,
                  stretch, stretch_map, translate, twist, twist_ramp)
from .program import EditProgram, apply_program

__all__ = ["BLEND_PARAMS", "BLENDS", "EditError", "EditProgram", "HandleSolve", "OPS", "apply",
           "apply_program", "bend_to", "blend_features", "blend_weight", "compose", "constant",
           "deform_by_handles", "hermite_of_length", "kabsch", "linear",
           "local_motion", "mix_weight", "move_points", "rigid", "rotate", "scale_radii",
           "smoothstep", "stretch", "stretch_map", "translate",
           "truncated_linear", "twist", "twist_ramp"]
