"""Pure geometry: curves, rotation-minimising frames, generalized cylinders, relative coords.

Imports nothing else of ngc_gen (DESIGN.md section 1)."""
from .arrays import GeometryShapeError
from .curves import BezierCurve, Curve, SplineCurve, curve_from_dict
from .cylinder import GeneralizedCylinder, Key
from .errors import GeometryError

__all__ = ["BezierCurve", "Curve", "GeneralizedCylinder", "GeometryError", "GeometryShapeError",
           "Key", "SplineCurve", "curve_from_dict"]
