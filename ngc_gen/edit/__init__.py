"""Editing: pure GC -> GC edits, handle deformation, part mixing, edit programs (docs/editing.md).

The neural codes never change: an edit only changes GCs (and part mixing only blends features),
so a fitted shape is deformed with no re-training. `ops`, `handles`, `blend` and `program` use
only ngc_gen.geometry and the part-mixing rule of ngc_gen.shape; a program applies to a
`ngc_gen.shape.Shape` (`Shape.edited`). Runners (edit.py) live in ngc_gen.app.

Names are loaded on first use (PEP 562), so `ngc_gen.edit.spec` and `ngc_gen.edit.errors` import
without torch: edit.py checks a program's structure before the heavy modules load.
"""
from __future__ import annotations

import importlib

_HOME = {
    **dict.fromkeys(["BLEND_PARAMS", "BLENDS", "blend_features", "blend_weight", "constant",
                     "linear", "mix_weight", "smoothstep", "truncated_linear"], "blend"),
    "EditError": "errors",
    **dict.fromkeys(["HandleSolve", "bend_to", "deform_by_handles", "hermite_of_length",
                     "kabsch"], "handles"),
    **dict.fromkeys(["OPS", "apply", "compose", "local_motion", "move_points", "rigid", "rotate",
                     "scale_radii", "stretch", "stretch_map", "translate", "twist",
                     "twist_ramp"], "ops"),
    **dict.fromkeys(["EditProgram", "apply_program"], "program"),
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
