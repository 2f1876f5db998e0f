"""Pure geometry: curves, rotation-minimising frames, generalized cylinders, relative coords.

Imports nothing else of ngc_gen (docs/architecture.md)."""
from .arrays import GeometryShapeError
from .curves import BezierCurve, Curve, SplineCurve, curve_from_dict
from .curves import bernstein_basis
from .cylinder import GeneralizedCylinder, Key
from .errors import GeometryError
from .smooth import smooth_min, smooth_min_all
from .union import fade_weight

__all__ = ["BezierCurve", "Curve", "GeneralizedCylinder", "GeometryError", "GeometryShapeError",
           "Key", "SplineCurve", "bernstein_basis", "curve_from_dict", "fade_weight",
           "smooth_min", "smooth_min_all"]
