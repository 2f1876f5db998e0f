"""Extraction of a world-space SDF (the DeepSDF baseline has no GCs to prefilter by): the same
grid, slabs and bricked marching cubes as the NGC paths.

Dense: every grid point. Coarse-to-fine (`coarse_step` s): the points of a lattice every s
indices first; a coarse cell (s^3 fine cells) is refined, i.e. all its grid points evaluated, if
its corners change sign or one of them has |F| < lipschitz x the cell's diagonal; every other
point takes its nearest coarse point's value. For a field whose slope is at most `lipschitz`,
no surface passes through a cell left coarse, every cell marching cubes meshes has exact corner
values, and the mesh equals the dense one (tests/extract/test_world.py).
"""
from __future__ import annotations

import time

import numpy as np
import torch

from .extractor import ExtractionResult
from .grid import Grid, lattice_points, slabs
from .marching import marching_cubes_mesh


def _evaluate(sdf_fn, pts: torch.Tensor, chunk: int) -> np.ndarray:
    pts = pts.float()
    return torch.cat([sdf_fn(pts[i:i + chunk]).float().cpu()
                      for i in range(0, len(pts), chunk)]).numpy()


def extract_world_mesh(sdf_fn, resolution: int = 256, bound: float = 1.0, *, chunk: int = 65536,
                       slab_points: int = 1 << 18, coarse_step: int | None = None,
                       lipschitz: float = 2.0) -> ExtractionResult:
    """sdf_fn(xyz (M, 3) float32) -> (M,) on the grid (every point, or coarse-to-fine with
    `coarse_step`, module docstring), then marching cubes."""
    t0 = time.perf_counter()
    grid = Grid(int(resolution), float(bound))
    if coarse_step:
        values, n_evals = _coarse_to_fine(sdf_fn, grid, int(coarse_step), lipschitz, chunk)
    else:
        values = np.empty(grid.n_points, dtype=np.float32)
        for lattice in slabs(grid.full(), slab_points):
            pts, flat = lattice_points(grid, lattice)
            values[flat.numpy()] = _evaluate(sdf_fn, pts, chunk)
        values, n_evals = values.reshape((grid.resolution,) * 3), grid.n_points
    mesh = marching_cubes_mesh(values, grid)
    stats = {"n_grid_points": grid.n_points, "n_network_evals": int(n_evals),
             "n_faces": len(mesh.faces), "seconds": time.perf_counter() - t0}
    return ExtractionResult(mesh, stats)


def _coarse_to_fine(sdf_fn, grid: Grid, step: int, lipschitz: float, chunk: int):
    R = grid.resolution
    c = np.arange(0, R, step)
    if c[-1] != R - 1:
        c = np.append(c, R - 1)
    pts, _ = lattice_points(grid, (c, c, c))
    coarse = _evaluate(sdf_fn, pts, chunk).reshape((len(c),) * 3)
    # each coarse cell: its 8 corners (min |F|, sign change) against its diagonal
    corners = np.stack([coarse[i:len(c) - 1 + i, j:len(c) - 1 + j, k:len(c) - 1 + k]
                        for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    diag = np.diff(c) * grid.spacing
    diag = np.sqrt(diag[:, None, None] ** 2 + diag[None, :, None] ** 2 + diag[None, None, :] ** 2)
    refine = ((corners.min(0) <= 0) & (corners.max(0) >= 0)) | \
        (np.abs(corners).min(0) < lipschitz * diag)
    # every grid point: its nearest coarse point's value; then the points of refined cells
    near = np.abs(np.arange(R)[:, None] - c[None, :]).argmin(1)
    values = coarse[np.ix_(near, near, near)].astype(np.float32)
    mask = np.zeros((R, R, R), dtype=bool)
    for i, j, k in np.argwhere(refine):
        mask[c[i]:c[i + 1] + 1, c[j]:c[j + 1] + 1, c[k]:c[k + 1] + 1] = True
    mask[np.ix_(c, c, c)] = False  # known already
    flat = np.flatnonzero(mask)
    if len(flat):
        ix, iy, iz = np.unravel_index(flat, (R, R, R))
        x = grid.axis()
        fine = torch.from_numpy(np.stack([x[ix], x[iy], x[iz]], 1))
        values.reshape(-1)[flat] = _evaluate(sdf_fn, fine, chunk)
    return values, len(c) ** 3 + len(flat)
