"""Coarse-to-fine refinement: evaluate every `factor`-th grid point, then only the fine points of
coarse blocks that may hold the zero level set; fill the rest by trilinear interpolation.

A block is the box between neighbouring coarse indices (coarse indices are 0, f, 2f, ... and
R - 1, so the last block may be shorter). A block is refined if its 8 corner values change sign
(points outside every GC count as positive), if none of its corners lies in a GC (a thin GC may
pass between coarse points; refining it costs geometry, the network only runs inside GCs), or if
every corner inside a GC has |value| <= margin * (block diagonal). For a 1-Lipschitz SDF a block
the surface passes through always passes that last test (each corner lies within one diagonal of
the surface point), so with margin >= 1 the refined grid agrees with the full grid on every cell
marching cubes uses and the mesh is the same. A learned SDF is only roughly 1-Lipschitz (and the
minimum over GCs jumps at GC boundaries), so in general refinement is APPROXIMATE: use it for
speed, and the exact path (refine=False) for the prefilter check and for metrics. `dilate` adds
neighbouring blocks for safety. Points never evaluated get trilinear interpolation of the coarse
values, which keeps the sign of an unrefined block.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .grid import Grid


@dataclass(frozen=True)
class Refinement:
    """factor: coarse step in grid cells; margin: in block diagonals; dilate: extra blocks."""

    factor: int = 4
    margin: float = 1.0
    dilate: int = 0

    def __post_init__(self):
        if int(self.factor) != self.factor or self.factor < 2:
            raise ValueError(f"refinement factor must be an integer >= 2, got {self.factor!r}")
        if not self.margin >= 0:
            raise ValueError(f"refinement margin must be >= 0, got {self.margin!r}")
        if int(self.dilate) != self.dilate or self.dilate < 0:
            raise ValueError(f"refinement dilate must be an integer >= 0, got {self.dilate!r}")


def coarse_indices(resolution: int, factor: int) -> np.ndarray:
    """(C,) grid indices 0, f, 2f, ..., always ending with resolution - 1."""
    c = np.arange(0, resolution, factor)
    return c if c[-1] == resolution - 1 else np.append(c, resolution - 1)


def block_marks(coarse: np.ndarray, covered: np.ndarray, c: np.ndarray, grid: Grid,
                ref: Refinement) -> np.ndarray:
    """coarse: (C, C, C) values (background where uncovered), covered: (C, C, C) bool ->
    (C-1, C-1, C-1) bool: blocks to refine."""
    n = len(c) - 1
    corners = [(dx, dy, dz) for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)]
    neg = np.zeros((n, n, n), dtype=np.int8)
    cov_abs = np.full((n, n, n), -np.inf, dtype=np.float32)   # max |v| over covered corners
    for dx, dy, dz in corners:
        sl = (slice(dx, dx + n), slice(dy, dy + n), slice(dz, dz + n))
        neg += coarse[sl] < 0
        cov_abs = np.maximum(cov_abs, np.where(covered[sl], np.abs(coarse[sl]), -np.inf))
    # block diagonal per block (the last block along an axis may be shorter)
    ext = np.diff(c).astype(np.float64) * grid.spacing
    diag = np.sqrt(ext[:, None, None] ** 2 + ext[None, :, None] ** 2 + ext[None, None, :] ** 2)
    no_info = np.isneginf(cov_abs)   # no corner inside a GC: a thin GC may still cross it
    marks = ((neg > 0) & (neg < 8)) | no_info | (cov_abs <= ref.margin * diag)
    if ref.dilate:
        k = 2 * ref.dilate + 1
        m = torch.from_numpy(marks.astype(np.float32))[None, None]
        marks = torch.nn.functional.max_pool3d(m, k, stride=1, padding=ref.dilate)[0, 0].numpy() > 0
    return marks


def _axis_blocks(c: np.ndarray, resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """For each grid index i: the block whose half-open range [c_b, c_{b+1}) holds it (the last
    block also holds R - 1) and the other block it borders (i = c_b belongs to blocks b-1 and b)."""
    i = np.arange(resolution)
    b = np.clip(np.searchsorted(c, i, "right") - 1, 0, len(c) - 2)
    other = np.where((i == c[b]) & (b > 0), b - 1, b)
    return b, other


def fine_mask(marks: np.ndarray, c: np.ndarray, resolution: int) -> np.ndarray:
    """(R, R, R) bool: grid points that lie in (the closed box of) some marked block."""
    b, o = _axis_blocks(c, resolution)
    m = marks[b] | marks[o]
    m = m[:, b] | m[:, o]
    return m[:, :, b] | m[:, :, o]


def coarse_point_mask(c: np.ndarray, resolution: int) -> np.ndarray:
    on = np.zeros(resolution, dtype=bool)
    on[c] = True
    return on[:, None, None] & on[None, :, None] & on[None, None, :]


def _lerp_weights(c: np.ndarray, resolution: int) -> tuple[np.ndarray, np.ndarray]:
    i = np.arange(resolution)
    b = np.clip(np.searchsorted(c, i, "right") - 1, 0, len(c) - 2)
    w = (i - c[b]) / (c[b + 1] - c[b])
    return b, w.astype(np.float32)


def fill_interpolated(values: np.ndarray, evaluated: np.ndarray, coarse: np.ndarray,
                      c: np.ndarray) -> None:
    """Trilinear interpolation of the coarse grid into the grid points not evaluated, in place,
    plane by plane (no second full-size grid)."""
    R = values.shape[0]
    b, w = _lerp_weights(c, R)
    # along axes 1 and 2 first: (C, R, R)
    t = coarse[:, b] * (1 - w)[None, :, None] + coarse[:, b + 1] * w[None, :, None]
    t = t[:, :, b] * (1 - w)[None, None, :] + t[:, :, b + 1] * w[None, None, :]
    for i in range(R):
        todo = ~evaluated[i]
        if todo.any():
            plane = t[b[i]] * (1 - w[i]) + t[b[i] + 1] * w[i]
            values[i][todo] = plane[todo]
