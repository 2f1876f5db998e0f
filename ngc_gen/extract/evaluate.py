"""Evaluate per-GC SDFs on grid points and keep the minimum over the GCs that contain each point.

For one GC and one lattice (the grid, or a coarse sub-grid) the points of its bounding box are
cut out by index ranges, their relative coordinates are computed once, in slabs, and used both
for the exact inside test (`GeneralizedCylinder.inside_relative`) and as the network input.
With `prefilter=False` every lattice point is sent to the network for every GC and the same inside
test masks the result afterwards: the reference the prefilter must match bit for bit.

Batch invariance: a network's result for one row can depend on how many rows share the call (BLAS
picks kernels by matrix shape). With `fixed_batch=True` every call of `sdf_fn` gets exactly
`chunk` rows (the last batch of each GC is zero-padded and the padding dropped), so a point's
value does not depend on which other points were evaluated with it, and the prefiltered grid
equals the dense one exactly for real networks too.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import torch
from tqdm.auto import tqdm

from ngc_gen.geometry import GeneralizedCylinder

from .grid import Grid, Lattice, lattice_points, n_slabs, restrict, slabs

SdfFn = Callable[[int, torch.Tensor], torch.Tensor]


class MinField:
    """A flat float32 value grid, +inf where no GC has been evaluated, lowered by `add_gc`.

    values: (R^3,) float32 tensor, C order. stats counts network rows and points."""

    def __init__(self, grid: Grid, sdf_fn: SdfFn, chunk: int = 65536, fixed_batch: bool = True,
                 device=None, slab_points: int = 1 << 18, prefilter: bool = True):
        if chunk < 1:
            raise ValueError(f"chunk must be a positive number of points, got {chunk}")
        self.grid, self.sdf_fn, self.chunk = grid, sdf_fn, int(chunk)
        self.fixed_batch, self.device = fixed_batch, device
        self.slab_points, self.prefilter = int(slab_points), prefilter
        self.values = torch.full((grid.n_points,), float("inf"), dtype=torch.float32)
        self.stats = {"n_network_evals": 0, "n_network_rows": 0, "n_network_calls": 0,
                      "n_relative": 0, "n_inside": 0, "seconds_network": 0.0,
                      "seconds_geometry": 0.0}

    # ---- planning ----------------------------------------------------------------------------
    def region(self, gc: GeneralizedCylinder, lattice: Lattice) -> Lattice | None:
        """The part of `lattice` to visit for this GC: its bounding box, or all of it (dense)."""
        if not self.prefilter:
            return lattice
        return restrict(lattice, self.grid.index_box(*gc.bounds()))

    def count_slabs(self, gcs, lattice: Lattice) -> int:
        return sum(n_slabs(self.region(gc, lattice), self.slab_points) for gc in gcs)

    # ---- evaluation --------------------------------------------------------------------------
    def add_gc(self, index: int, gc: GeneralizedCylinder, lattice: Lattice,
               mask: torch.Tensor | None = None, bar: tqdm | None = None) -> None:
        """Evaluate GC `index` at the points of `lattice` (those with mask[flat] True if a flat
        (R^3,) bool mask is given) and take the minimum into `values` where the GC contains them."""
        region = self.region(gc, lattice)
        if region is None:
            return
        batch = _Batcher(self, index)
        for slab in slabs(region, self.slab_points):
            t0 = time.perf_counter()
            pts, flat = lattice_points(self.grid, slab)
            if mask is not None:
                keep = mask[flat]
                pts, flat = pts[keep], flat[keep]
            if len(flat):
                rel = gc.to_relative(pts)
                inside = GeneralizedCylinder.inside_relative(rel)
                self.stats["n_relative"] += len(flat)
                self.stats["n_inside"] += int(inside.sum())
                if self.prefilter:
                    rel, flat, inside = rel[inside], flat[inside], None
                self.stats["seconds_geometry"] += time.perf_counter() - t0
                batch.push(rel.to(torch.float32), flat, inside)
            if bar is not None:
                bar.update(1)
        batch.finish()


class _Batcher:
    """Collects rows of one GC across slabs and sends them to the network in chunks."""

    def __init__(self, field: MinField, index: int):
        self.f, self.index = field, index
        self.rel: list[torch.Tensor] = []
        self.flat: list[torch.Tensor] = []
        self.inside: list[torch.Tensor] = []
        self.n = 0

    def push(self, rel: torch.Tensor, flat: torch.Tensor, inside: torch.Tensor | None) -> None:
        if len(flat) == 0:
            return
        self.rel.append(rel)
        self.flat.append(flat)
        self.inside.append(torch.ones(len(flat), dtype=torch.bool) if inside is None else inside)
        self.n += len(flat)
        if self.n >= self.f.chunk:
            self._drain(final=False)

    def finish(self) -> None:
        if self.n:
            self._drain(final=True)

    def _drain(self, final: bool) -> None:
        rel, flat, inside = torch.cat(self.rel), torch.cat(self.flat), torch.cat(self.inside)
        c = self.f.chunk
        stop = len(flat) if final else (len(flat) // c) * c
        for s in range(0, stop, c):
            self._run(rel[s:s + c], flat[s:s + c], inside[s:s + c])
        self.rel, self.flat, self.inside = [rel[stop:]], [flat[stop:]], [inside[stop:]]
        self.n = len(flat) - stop

    def _run(self, rel: torch.Tensor, flat: torch.Tensor, inside: torch.Tensor) -> None:
        f, n = self.f, len(flat)
        if f.fixed_batch and n < f.chunk:
            rel = torch.cat([rel, rel.new_zeros(f.chunk - n, 3)])
        t0 = time.perf_counter()
        out = f.sdf_fn(self.index, rel.to(f.device) if f.device is not None else rel)
        out = torch.as_tensor(out).detach()
        f.stats["seconds_network"] += time.perf_counter() - t0
        if out.numel() != len(rel):
            raise ValueError(f"sdf_fn(gc_index={self.index}, rel (M, 3)) must return M = "
                             f"{len(rel)} values, got shape {tuple(out.shape)}")
        out = out.reshape(-1)[:n].to(device="cpu", dtype=torch.float32)
        f.stats["n_network_evals"] += n
        f.stats["n_network_rows"] += len(rel)
        f.stats["n_network_calls"] += 1
        out, flat = out[inside], flat[inside]
        if not bool(torch.isfinite(out).all()):
            raise ValueError(f"sdf_fn returned non-finite values (NaN/inf) for GC {self.index} at "
                             f"{int((~torch.isfinite(out)).sum())} points inside it; check the "
                             "network/checkpoint")
        f.values[flat] = torch.minimum(f.values[flat], out)


def gc_list(gcs) -> list[GeneralizedCylinder]:
    gcs = list(gcs)
    for i, gc in enumerate(gcs):
        if not isinstance(gc, GeneralizedCylinder):
            raise TypeError(f"gcs[{i}] must be a GeneralizedCylinder, got {type(gc).__name__}")
    return gcs


def fill_background(values: torch.Tensor, background: float) -> int:
    """Points no GC contains (still +inf) get the positive background value, in place
    (masked_fill: no index array of the uncovered points). Returns how many were covered."""
    uncovered = torch.isinf(values)
    values.masked_fill_(uncovered, background)
    return values.numel() - int(torch.count_nonzero(uncovered))


def as_numpy_grid(values: torch.Tensor, grid: Grid) -> np.ndarray:
    R = grid.resolution
    return values.numpy().reshape(R, R, R)
