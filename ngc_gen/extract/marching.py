"""Marching cubes (scikit-image, Lewiner) on a value grid, with vertices in world coordinates."""
from __future__ import annotations

import numpy as np
import trimesh
from skimage.measure import marching_cubes

from .grid import Grid


def empty_mesh() -> trimesh.Trimesh:
    return trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64),
                           process=False)


def marching_cubes_grid(values: np.ndarray, origin, spacing: float, level: float = 0.0,
                        process: bool = True, float32_spacing: bool = False) -> trimesh.Trimesh:
    """The level-`level` surface of a value grid (negative inside) whose index (i, j, k) lies at
    origin + spacing * (i, j, k): the one place marching cubes runs (scikit-image, Lewiner).

    Faces are oriented with normals toward increasing values (outward for an SDF), so a closed
    surface has positive volume. No crossing of `level` gives an empty mesh, not an error.
    float32_spacing: scale in scikit-image (float32 vertices before the shift), as the procedural
    creatures were built, which keeps the shipped creature set bit-identical; otherwise float64."""
    values = np.asarray(values)
    if not (values.min() < level < values.max()):
        return empty_mesh()
    # 'descent' orients faces with the object (lower values) behind them: outward for an SDF
    verts, faces, _, _ = marching_cubes(
        values, level=level, gradient_direction="descent", allow_degenerate=False,
        spacing=(float(spacing),) * 3 if float32_spacing else (1.0, 1.0, 1.0))
    scale = 1.0 if float32_spacing else float(spacing)
    verts = verts.astype(np.float64) * scale + np.asarray(origin, dtype=np.float64)
    return trimesh.Trimesh(vertices=verts, faces=faces, process=process)


def marching_cubes_mesh(values: np.ndarray, grid: Grid, level: float = 0.0) -> trimesh.Trimesh:
    """values: (R, R, R) float grid over `grid` (negative inside) -> the level-`level` surface,
    vertices in world coordinates inside [-bound, bound]^3."""
    values = np.asarray(values)
    R = grid.resolution
    if values.shape != (R, R, R):
        raise ValueError(f"values must have shape {(R, R, R)}, got {values.shape}")
    mesh = marching_cubes_grid(values, (-grid.bound,) * 3, grid.spacing, level, process=False)
    if len(mesh.faces):
        np.clip(mesh.vertices, -grid.bound, grid.bound, out=mesh.vertices)  # rounding only
        mesh = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=True)
    return mesh
