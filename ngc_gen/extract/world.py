"""Dense extraction of a world-space SDF (the DeepSDF baseline has no GCs to prefilter by):
the same grid, slabs and bricked marching cubes as the NGC paths."""
from __future__ import annotations

import time

import numpy as np
import torch

from .extractor import ExtractionResult
from .grid import Grid, lattice_points, slabs
from .marching import marching_cubes_mesh


def extract_world_mesh(sdf_fn, resolution: int = 256, bound: float = 1.0, *, chunk: int = 65536,
                       slab_points: int = 1 << 18) -> ExtractionResult:
    """sdf_fn(xyz (M, 3) float32) -> (M,) evaluated at every grid point, then marching cubes."""
    t0 = time.perf_counter()
    grid = Grid(int(resolution), float(bound))
    values = np.empty(grid.n_points, dtype=np.float32)
    for lattice in slabs(grid.full(), slab_points):
        pts, flat = lattice_points(grid, lattice)
        pts = pts.float()
        out = torch.cat([sdf_fn(pts[i:i + chunk]).float().cpu() for i in range(0, len(pts), chunk)])
        values[flat.numpy()] = out.numpy()
    values = values.reshape((grid.resolution,) * 3)
    mesh = marching_cubes_mesh(values, grid)
    stats = {"n_grid_points": grid.n_points, "n_network_evals": grid.n_points,
             "n_faces": len(mesh.faces), "seconds": time.perf_counter() - t0}
    return ExtractionResult(mesh, stats)
