"""Polynomial smooth minimum of two SDFs (Quilez): the smooth union every layer uses.

h = clamp(1/2 + (b - a) / (2k), 0, 1), smin = lerp(b, a, h) - k h (1 - h). It equals min(a, b)
where |a - b| >= k, lies in [min - k/4, min] everywhere, and k = 0 gives min exactly. Folding
n fields one after another therefore stays within (n - 1) k / 4 below their minimum.
"""
from __future__ import annotations

import numpy as np
import torch

from .errors import GeometryError


def smooth_min(a, b, k: float):
    """a, b: torch tensors or numpy arrays of one shape; k >= 0 the blend width (SDF units)."""
    k = float(k)
    if not k >= 0.0:
        raise GeometryError(f"smooth-min width k must be >= 0, got {k}", field="k")
    if k == 0.0:
        return torch.minimum(a, b) if isinstance(a, torch.Tensor) else np.minimum(a, b)
    h = (0.5 + 0.5 * (b - a) / k).clip(0.0, 1.0)
    return b + h * (a - b) - k * h * (1.0 - h)
