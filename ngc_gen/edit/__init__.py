"""Editing: pure GC -> GC edits, handle deformation, part-mixing blends (DESIGN.md section 4).

The neural codes never change: an edit only changes GCs (and part mixing only blends features),
so a fitted shape is deformed with no re-training. Imports only ngc_gen.geometry (and numpy,
scipy, torch).
"""
from .blend import (BLENDS, blend_features, blend_weight, constant, linear, smooth_min,
                    smooth_min_all, smoothstep, truncated_linear)
from .errors import EditError
from .handles import HandleSolve, bend_to, deform_by_handles, hermite_of_length, kabsch
from .ops import (OPS, apply, compose, move_points, rigid, rotate, scale_radii, stretch,
                  stretch_map, translate, twist)

__all__ = ["BLENDS", "EditError", "HandleSolve", "OPS", "apply", "bend_to", "blend_features",
           "blend_weight", "compose", "constant", "deform_by_handles", "hermite_of_length",
           "kabsch", "linear", "move_points", "rigid", "rotate", "scale_radii", "smooth_min",
           "smooth_min_all", "smoothstep", "stretch", "stretch_map", "translate",
           "truncated_linear", "twist"]
