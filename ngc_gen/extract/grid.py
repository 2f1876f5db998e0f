"""The extraction grid: `resolution` points per axis over [-bound, bound]^3, and its sub-boxes.

Grid point (i, j, k) sits at world position -bound + (i, j, k) * spacing, with
spacing = 2 bound / (resolution - 1); its flat index is (i R + j) R + k (C order of an (R, R, R)
array, the layout marching cubes reads). A *lattice* is a sub-grid given by three sorted arrays of
grid indices (all of them for the full grid, every 4th for the coarse pass of refinement).
Boxes are cut from a lattice by index ranges (a binary search per axis), never by testing every
grid point, and are walked in slabs of whole planes so memory stays bounded.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np
import torch

Lattice = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Grid:
    """A regular grid of `resolution`^3 points over [-bound, bound]^3."""

    resolution: int
    bound: float = 1.0

    def __post_init__(self):
        if int(self.resolution) != self.resolution or self.resolution < 2:
            raise ValueError(f"resolution must be an integer >= 2, got {self.resolution!r}")
        if not (np.isfinite(self.bound) and self.bound > 0):
            raise ValueError(f"bound must be positive and finite, got {self.bound!r}")

    @property
    def spacing(self) -> float:
        return 2.0 * self.bound / (self.resolution - 1)

    @property
    def n_points(self) -> int:
        return self.resolution ** 3

    def axis(self) -> np.ndarray:
        """(R,) float64 world coordinate of each index along any axis."""
        return np.linspace(-self.bound, self.bound, self.resolution)

    def coords(self, index: np.ndarray) -> np.ndarray:
        """World coordinate (float64) of integer indices along an axis; indices past R - 1
        (the sparse path's padded lattice) continue the spacing. Equal to `axis()` where both
        are defined, so every path sees the same points."""
        index = np.asarray(index, dtype=np.int64)
        R = self.resolution
        return np.where(index < R, self.axis()[np.minimum(index, R - 1)],
                        -self.bound + index * self.spacing)

    def full(self) -> Lattice:
        r = np.arange(self.resolution)
        return r, r, r

    def index_box(self, lo, hi) -> tuple[np.ndarray, np.ndarray] | None:
        """Inclusive index ranges (first (3,), last (3,)) of the grid points inside the world box
        [lo, hi], widened by one index each side against rounding; None if it misses the grid."""
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        first = np.floor((lo + self.bound) / self.spacing).astype(np.int64) - 1
        last = np.ceil((hi + self.bound) / self.spacing).astype(np.int64) + 1
        first, last = np.maximum(first, 0), np.minimum(last, self.resolution - 1)
        return None if np.any(first > last) else (first, last)


def restrict(lattice: Lattice, box: tuple[np.ndarray, np.ndarray] | None) -> Lattice | None:
    """The part of `lattice` whose indices fall in the inclusive index `box`; None if empty."""
    if box is None:
        return None
    out = []
    for idx, a, b in zip(lattice, *box):
        part = idx[np.searchsorted(idx, a, "left"):np.searchsorted(idx, b, "right")]
        if len(part) == 0:
            return None
        out.append(part)
    return tuple(out)


def slabs(lattice: Lattice, max_points: int) -> Iterator[Lattice]:
    """Split a lattice along its first axis into slabs of at most `max_points` points (at
    least one plane each)."""
    ix, iy, iz = lattice
    planes = max(1, int(max_points) // (len(iy) * len(iz)))
    for s in range(0, len(ix), planes):
        yield ix[s:s + planes], iy, iz


def n_slabs(lattice: Lattice | None, max_points: int) -> int:
    if lattice is None:
        return 0
    planes = max(1, int(max_points) // (len(lattice[1]) * len(lattice[2])))
    return -(-len(lattice[0]) // planes)


def lattice_points(grid: Grid, lattice: Lattice) -> tuple[torch.Tensor, torch.Tensor]:
    """World positions (N, 3) float64 and flat grid indices (N,) int64 of a lattice's points,
    in C order (first axis slowest)."""
    ix, iy, iz = (torch.from_numpy(np.ascontiguousarray(a, dtype=np.int64)) for a in lattice)
    R = grid.resolution
    flat = ((ix[:, None, None] * R + iy[None, :, None]) * R + iz[None, None, :]).reshape(-1)
    x = torch.from_numpy(grid.axis())
    shape = (len(ix), len(iy), len(iz))
    pts = torch.stack([x[ix][:, None, None].expand(shape), x[iy][None, :, None].expand(shape),
                       x[iz][None, None, :].expand(shape)], -1).reshape(-1, 3)
    return pts, flat
