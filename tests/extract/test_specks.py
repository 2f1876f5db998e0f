"""Specks (components under 2 cells wide) are left out of every extracted mesh."""
import numpy as np

from ngc_gen.eval.fitting import component_sizes
from ngc_gen.extract.grid import Grid
from ngc_gen.extract.marching import marching_cubes_mesh


def ball_field(grid: Grid, radius: float = 0.5) -> np.ndarray:
    x = grid.axis()
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    return (np.sqrt(X ** 2 + Y ** 2 + Z ** 2) - radius).astype(np.float32)


def test_lone_samples_are_dropped_and_real_parts_kept():
    grid = Grid(32, 1.0)
    values = ball_field(grid)
    ball = marching_cubes_mesh(values, grid)
    # a floater (one sample below zero, its neighbours on a face diagonal included: marching
    # cubes still separates it) and a pinhole bubble inside the ball
    values[3, 3, 3] = -1e-3
    values[4, 4, 3] = -1e-3
    values[16, 16, 16] = 0.01
    raw = marching_cubes_mesh(values, grid, keep_specks=True)
    assert len(component_sizes(raw)) == 4
    clean = marching_cubes_mesh(values, grid)
    assert np.array_equal(clean.vertices, ball.vertices)
    assert np.array_equal(clean.faces, ball.faces)
    # a part 3 samples long is something the grid resolves: kept
    values[3:6, 3, 3] = -0.05
    assert len(component_sizes(marching_cubes_mesh(values, grid))) == 2


def test_a_field_of_specks_only_gives_an_empty_mesh():
    grid = Grid(16, 1.0)
    values = np.ones((16,) * 3, dtype=np.float32)
    values[5, 5, 5] = -1.0
    assert len(marching_cubes_mesh(values, grid, keep_specks=True).faces) == 8
    assert len(marching_cubes_mesh(values, grid).faces) == 0
