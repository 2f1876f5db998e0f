"""The blended union of GCs: a partition of unity over the GCs that hold a point.

The min over GCs (the paper's union) has two seams: where GCs overlap it takes the smaller of
two estimates of one SDF, and where a GC's boundary lies inside another GC the min stops seeing
that GC at once. The blend weighs each GC by where the point lies in it instead:

    w_j = FLOOR + (1 - FLOOR) smoothstep((1 - rho_j) / width),   F = sum_j w_j f_j / sum_j w_j

over the GCs j that hold the point, rho_j its relative radius in GC j (sqrt of
`GeneralizedCylinder.relative_measure`: the radii across the tube, the cap lengths past an end,
so the weight fades toward the ends too). w_j is 1 deeper than 1 - width and falls smoothly to
FLOOR on the boundary, so a GC's field fades out before its boundary wherever another GC holds
the point, and a point only one GC holds keeps that GC's value (the weights cancel). FLOOR keeps
the sum positive on a boundary; the step the mean leaves where a GC ends is FLOOR x the two
fields' difference. `BlendAccumulator` folds the weighted mean or, with k > 0, a weighted soft
minimum (the default, `model.union.k`), which keeps the mean where GCs agree and the min's
material where they do not. The weight depends only on the point's relative coordinates in one
GC, so a changed GC changes only its own terms (per-GC value caches stay valid).
"""
from __future__ import annotations

import numpy as np
import torch

from .errors import GeometryError

#: weight on a GC's boundary: the sum over the GCs holding a point stays positive
FLOOR = 1e-6


def check_width(width: float) -> float:
    """A blend width (relative radius), > 0 and <= 1."""
    width = float(width)
    if not 0.0 < width <= 1.0:
        raise GeometryError(f"blend width must be in (0, 1] (a relative radius), got {width}",
                            field="union.width")
    return width


def fade_weight(measure, width: float):
    """Blend weight of a GC at points of relative measure rho^2 (numpy or torch (N,)) -> (N,):
    1 deeper than rho = 1 - width, a smoothstep down to FLOOR at rho = 1 (and beyond)."""
    width = check_width(width)
    if isinstance(measure, torch.Tensor):
        s = ((1.0 - measure.clamp(min=0.0).sqrt()) / width).clamp(0.0, 1.0)
    else:
        s = np.clip((1.0 - np.sqrt(np.maximum(measure, 0.0))) / width, 0.0, 1.0)
    return FLOOR + (1.0 - FLOOR) * (s * s * (3.0 - 2.0 * s))


class BlendAccumulator:
    """The blended union of n points, folded one GC at a time (in GC order, so every path that
    folds the same values in the same order gets the same floats).

    k = 0: the weighted mean sum_j w_j f_j / sum_j w_j. k > 0: the weighted soft minimum
    F = -k log(sum_j w_j exp(-f_j / k) / sum_j w_j): equal to the mean's value where the GCs
    agree (equal f_j give that f), the smaller value where they differ by more than about k
    (a thin part's own GC keeps its material where a coarser GC's estimate smooths it away).
    Where a GC fades out its term is lifted by k ln(1 / w_j): the field stays continuous across
    its boundary where it undercuts the other GCs by less than k ln(1 / FLOOR) (0.041 for
    k = 0.003), and steps by the rest beyond (the min steps by all of it)."""

    def __init__(self, n: int, width: float, k: float = 0.0):
        self.width, self.k = check_width(width), float(k)
        if not self.k >= 0.0:
            raise GeometryError(f"blend k must be >= 0 (0: the weighted mean), got {k}",
                                field="union.k")
        self.den = np.zeros(n, dtype=np.float64)
        self.acc = np.zeros(n, dtype=np.float64)          # sum w f (k = 0) or sum w e^-(f-m)/k
        self.low = np.full(n, np.inf, dtype=np.float64)   # k > 0: the running minimum m

    def add(self, idx, f: np.ndarray, measure: np.ndarray) -> None:
        """Fold one GC's values f at points idx (unique indices or a mask) of measure rho^2."""
        w = fade_weight(np.asarray(measure, dtype=np.float32), self.width).astype(np.float64)
        f = np.asarray(f, dtype=np.float64)
        self.den[idx] += w
        if self.k == 0.0:
            self.acc[idx] += w * f
            return
        m0 = self.low[idx]
        m1 = np.minimum(m0, f)
        with np.errstate(invalid="ignore"):
            scale = np.where(np.isfinite(m0), np.exp(-(m0 - m1) / self.k), 0.0)
        self.acc[idx] = self.acc[idx] * scale + w * np.exp(-(f - m1) / self.k)
        self.low[idx] = m1

    def result(self) -> np.ndarray:
        """(n,) float32 field; +inf where no GC held the point."""
        held = self.den > 0
        out = np.full(len(self.den), np.inf, dtype=np.float64)
        if self.k == 0.0:
            out[held] = self.acc[held] / self.den[held]
        else:
            out[held] = self.low[held] - self.k * np.log(self.acc[held] / self.den[held])
        return out.astype(np.float32)
