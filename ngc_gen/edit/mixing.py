"""Part mixing and smooth union for extraction (paper Sec. 3.2, Fig. 11).

Mixing: GC j of shape A evaluates h(PE(u, a, b), blend(g(f_A(t)), g(f_B(t)), w(t))), with f_B
the end-feature lerp of another GC's code (the same or another shape, from the same network:
features of different networks do not mean the same thing). w = 0 is shape A's own part,
w = 1 ("replace") is part B inside A's GC. `mixed_sdf_fn` gives the `sdf_fn(gc_index, rel)` that
`ngc_gen.extract.extract_mesh` takes.

Smooth union: `extract_mesh` takes the hard minimum over the GCs containing a grid point, which
leaves a crease where two parts overlap. `extract_smooth_union` evaluates each GC's field on its
own (the extractor's exact prefiltered path, one GC at a time) and folds them with the polynomial
smooth minimum of width k where they overlap; k = 0 is `extract_mesh` itself.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import torch

from ngc_gen.extract import ExtractionResult, Grid, MinField, extract_mesh, marching_cubes_mesh
from ngc_gen.extract.evaluate import as_numpy_grid, fill_background, gc_list

from ngc_gen.geometry import smooth_min

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
    """Like `extract_mesh` (exact path), but GC fields that overlap are joined by a smooth union
    of width k (world/SDF units) instead of the hard minimum. k = 0 calls `extract_mesh`.

    Each GC is evaluated where it contains a grid point (same prefilter and fixed batches as
    the extractor), then folded in GC order with `smooth_min` where both fields exist: the
    result lies within (K - 1) k / 4 below the hard minimum and equals it where the fields
    differ by more than k."""
    k = float(k)
    if not k >= 0.0:
        raise EditError(f"smooth union width must be >= 0, got {k}", field="smooth_union",
                        fix="use 0 for the hard minimum, or a small width like 0.02")
    if k == 0.0:
        return extract_mesh(gcs, sdf_fn, resolution, bound, chunk=chunk, background=background,
                            device=device)
    t_start = time.perf_counter()
    gcs = gc_list(gcs)
    grid = Grid(int(resolution), float(bound))
    background = grid.spacing if background is None else float(background)
    acc = torch.full((grid.n_points,), float("inf"), dtype=torch.float32)
    stats: dict = {}
    for j, gc in enumerate(gcs):
        field = MinField(grid, sdf_fn, chunk=chunk, fixed_batch=True, device=device)
        field.add_gc(j, gc, grid.full())
        idx = torch.nonzero(torch.isfinite(field.values)).squeeze(1)
        v, a = field.values[idx], acc[idx]
        acc[idx] = torch.where(torch.isfinite(a), smooth_min(a, v, k), v)
        for key, val in field.stats.items():
            stats[key] = stats.get(key, 0) + val
        del field
    n_covered = fill_background(acc, background)
    t0 = time.perf_counter()
    mesh = marching_cubes_mesh(as_numpy_grid(acc, grid), grid)
    stats.update(n_grid_points=grid.n_points, n_covered=n_covered, n_gcs=len(gcs),
                 resolution=grid.resolution, bound=grid.bound, background=background,
                 smooth_union=k, n_faces=len(mesh.faces), n_vertices=len(mesh.vertices),
                 seconds_marching=time.perf_counter() - t0)
    stats["seconds"] = time.perf_counter() - t_start
    return ExtractionResult(mesh, stats)
