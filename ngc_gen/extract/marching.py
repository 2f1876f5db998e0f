"""Marching cubes (scikit-image, Lewiner) on a value grid, with vertices in world coordinates."""
from __future__ import annotations

import numpy as np
import trimesh
from skimage.measure import marching_cubes

from .grid import Grid


def empty_mesh() -> trimesh.Trimesh:
    return trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64),
                           process=False)


def marching_cubes_mesh(values: np.ndarray, grid: Grid, level: float = 0.0) -> trimesh.Trimesh:
    """values: (R, R, R) float grid over `grid` (negative inside) -> the level-`level` surface.

    Vertices land at -bound + index * spacing (world coordinates, inside [-bound, bound]^3); faces
    are oriented with normals pointing to increasing values (outward for an SDF), so a closed
    surface has positive volume. No crossing of `level` gives an empty mesh, not an error."""
    values = np.asarray(values)
    R = grid.resolution
    if values.shape != (R, R, R):
        raise ValueError(f"values must have shape {(R, R, R)}, got {values.shape}")
    if not (values.min() < level < values.max()):
        return empty_mesh()
    # 'descent' orients faces with the object (lower values) behind them: outward for an SDF
    verts, faces, _, _ = marching_cubes(values, level=level, gradient_direction="descent",
                                        allow_degenerate=False)
    verts = verts.astype(np.float64) * grid.spacing - grid.bound
    np.clip(verts, -grid.bound, grid.bound, out=verts)  # rounding only: indices lie in [0, R-1]
    return trimesh.Trimesh(vertices=verts, faces=faces, process=True)
