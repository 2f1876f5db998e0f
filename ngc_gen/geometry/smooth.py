"""The smooth minimum: a smooth union of two SDFs with blend width k (one home for numpy and torch).

Polynomial (quadratic) smooth minimum (Quilez): min(a, b) - max(k - |a - b|, 0)^2 / (4k). It equals
min(a, b) where |a - b| >= k, lies at most k/4 below it (so a smooth union never grows a part by
more than k/4 in field units: the bound GC annotations rely on), and k = 0 is min exactly.
"""
from __future__ import annotations

import numpy as np
import torch

from .errors import GeometryError


def smooth_min(a, b, k: float):
    """Smooth minimum of a and b (numpy arrays or torch tensors of one shape), width k >= 0."""
    k = float(k)
    if not k >= 0.0:
        raise GeometryError(f"smooth-union width k must be >= 0, got {k}", field="smooth_union")
    if isinstance(a, torch.Tensor):
        if k == 0.0:
            return torch.minimum(a, b)
        h = (k - (a - b).abs()).clamp(min=0.0) / k
        return torch.minimum(a, b) - h * h * (k * 0.25)
    if k == 0.0:
        return np.minimum(a, b)
    h = np.clip(k - np.abs(a - b), 0.0, None) / k
    return np.minimum(a, b) - h * h * (k * 0.25)


def smooth_min_all(d, k: float):
    """Smooth union of the K columns of d (N, K) -> (N,), folded pairwise in column order; lies in
    [min - (K - 1) k / 4, min]. The loop runs over the K GCs (a handful), never over points."""
    out = d[:, 0]
    for j in range(1, d.shape[1]):
        out = smooth_min(out, d[:, j], k)
    return out
