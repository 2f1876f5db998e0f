"""Part mixing and smooth union for extraction (paper Sec. 3.2, Fig. 11).

Mixing: GC j of shape A evaluates h(PE(u, a, b), blend(g(f_A(t)), g(f_B(t)), w(t))), with f_B
the end-feature lerp of another GC's code (the same or another shape, from the same network:
features of different networks do not mean the same thing). w = 0 is shape A's own part,
w = 1 ("replace") is part B inside A's GC. `mixed_sdf_fn` gives the `sdf_fn(gc_index, rel)` that
`ngc_gen.extract.extract_mesh` takes.

Smooth union: the hard minimum over the GCs containing a grid point leaves a crease where two
parts overlap; `extract_smooth_union` asks the extractor for the polynomial smooth minimum of
width k instead (`extract_mesh(..., smooth=k)`); k = 0 is the hard minimum.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch

from ngc_gen.extract import ExtractionResult, extract_mesh, per_gc_rows

from .blend import Constant, blend_features
from .errors import EditError


@dataclass(frozen=True)
class PartMix:
    """Blend a GC's features with those of `code` (code_dim,) by weight w(t) (t the network's
    parameter along the GC; see `ngc_gen.edit.blend`). `source` names where the code came from
    (for metrics and messages)."""

    code: torch.Tensor
    weight: Callable
    source: str = ""


def _is_replace(weight) -> bool:
    return isinstance(weight, Constant) and float(weight.w) == 1.0


def mixed_sdf_fn(decoder, codes: torch.Tensor, mixes: dict[int, PartMix] | None = None):
    """sdf_fn(gc_index, rel) for `extract_mesh`: GC j with its own code codes[j], or blended
    with mixes[j]. decoder: an NGCDecoder (features / sdf_from_features); codes: (K, code_dim).

    Without mixes (or for an unmixed GC) this is exactly `decoder(codes[j], rel)`; a constant
    weight of 1 uses part B's features directly (exactly B's field in A's GC)."""
    mixes = dict(mixes or {})
    for j, m in mixes.items():
        if not 0 <= j < len(codes):
            raise EditError(f"mix targets GC index {j}, but the shape has {len(codes)} GCs",
                            op="mix")
        if m.code.shape != codes[j].shape:
            raise EditError(f"source code has shape {tuple(m.code.shape)}, the network's codes "
                            f"{tuple(codes[j].shape)}", op="mix", field="source",
                            fix="mix parts of shapes fitted with the same network")

    @torch.no_grad()
    def fn(j: int, rel: torch.Tensor) -> torch.Tensor:
        mix = mixes.get(j)
        if mix is None:
            return decoder(codes[j].expand(len(rel), -1), rel)
        u = rel[:, 0]
        fb = decoder.features(mix.code.to(rel.device).expand(len(rel), -1), u)
        if _is_replace(mix.weight):
            feats = fb
        else:
            fa = decoder.features(codes[j].expand(len(rel), -1), u)
            feats = blend_features(fa, fb, ((u + 1.0) * 0.5).clamp(0.0, 1.0), mix.weight)
        return decoder.sdf_from_features(rel, feats)

    return fn


def extract_smooth_union(gcs, sdf_fn, resolution: int = 256, bound: float = 1.0, k: float = 0.0,
                         *, chunk: int = 65536, background: float | None = None,
                         device=None) -> ExtractionResult:
    """`extract_mesh` of a per-GC sdf_fn(j, rel) with GC fields that overlap joined by a smooth
    union of width k (world/SDF units) instead of the hard minimum (k = 0): folded in GC order,
    the result lies within (K - 1) k / 4 below the hard minimum and equals it where the fields
    differ by more than k."""
    k = float(k)
    if not k >= 0.0:
        raise EditError(f"smooth union width must be >= 0, got {k}", field="smooth_union",
                        fix="use 0 for the hard minimum, or a small width like 0.02")
    return extract_mesh(gcs, per_gc_rows(sdf_fn), resolution, bound, smooth=k, chunk=chunk,
                        background=background, device=device)
