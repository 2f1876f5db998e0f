"""Folding per-GC values into the shape's field: min, smooth min (in GC order) or the blended
union (weights from each point's measure in each GC, summed in GC order); the dense and the
sparse paths fold with these, so their values agree."""
from __future__ import annotations

import numpy as np

from ngc_gen.geometry.smooth import smooth_min
from ngc_gen.geometry.union import BlendAccumulator


def fold_into(acc: np.ndarray, flat: np.ndarray, v: np.ndarray, smooth: float) -> None:
    """acc[flat] <- fold(acc[flat], v) in place (flat unique): min, or smooth-min where both
    are finite (the first GC holding a point just sets it)."""
    a = acc[flat]
    if smooth == 0.0:
        acc[flat] = np.minimum(a, v)
        return
    with np.errstate(invalid="ignore"):
        both = np.isfinite(a)
        acc[flat] = np.where(both, smooth_min(a, v, smooth), v).astype(np.float32)


def fold(values: list[np.ndarray], inside: list[np.ndarray], smooth: float,
         blend: float = 0.0, measures: list[np.ndarray] | None = None,
         blend_k: float = 0.0) -> np.ndarray:
    """Min (smooth = 0) or smooth-min of width `smooth` over the GCs holding each point, in GC
    order (the same fold as the dense path), or with blend > 0 the blended union of width blend
    and softness blend_k (`BlendAccumulator`; weights from the points' `measures` in each GC,
    folded in GC order as the dense path does); +inf where no GC holds the point."""
    if blend > 0:
        acc = BlendAccumulator(len(values[0]), blend, blend_k)
        for v, ins, m in zip(values, inside, measures):
            acc.add(ins, v[ins], m[ins])
        return acc.result()
    acc = None
    for v, ins in zip(values, inside):
        v = np.where(ins, v, np.float32(np.inf)).astype(np.float32)
        if acc is None:
            acc = v
        elif smooth == 0.0:
            acc = np.minimum(acc, v)
        else:
            with np.errstate(invalid="ignore"):
                both = np.isfinite(acc) & np.isfinite(v)
                acc = np.where(both, smooth_min(acc, v, smooth), np.minimum(acc, v))
            acc = acc.astype(np.float32)
    return acc
