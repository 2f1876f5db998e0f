"""Off-screen renders: the grid has the asked size, shows the meshes, and is written atomically."""
import warnings

import numpy as np
import pytest
import trimesh

from ngc_gen.viz import render_grid

pytest.importorskip("pyvista")


def test_grid_shows_each_mesh_in_its_cell(tmp_path):
    from PIL import Image

    trimesh.creation.icosphere(subdivisions=2).export(tmp_path / "sphere.ply")
    sphere = trimesh.load(tmp_path / "sphere.ply", process=False)  # carries PLY metadata
    (tmp_path / "sphere.ply").unlink()
    box = trimesh.creation.box()
    out = tmp_path / "grid.png"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. metadata pyvista cannot store
        render_grid([[sphere, box], [None, (box, sphere)]], out, labels=["a", "b"],
                    cell=(120, 100))
    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    assert img.shape == (200, 240, 3)
    drawn = (np.abs(img - 255).sum(-1) > 30)
    cells = [drawn[r * 100 + 20:(r + 1) * 100, c * 120:(c + 1) * 120].mean()
             for r in range(2) for c in range(2)]
    assert cells[0] > 0.05 and cells[1] > 0.05 and cells[3] > 0.05  # meshes drawn
    assert cells[2] < 0.01  # the empty cell stays white
    assert [p.name for p in tmp_path.iterdir()] == ["grid.png"]  # no temp file left


def _coverage(path):
    from PIL import Image

    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    drawn = np.abs(img - 255).sum(-1) > 30
    return drawn[:, :120].mean(), drawn[:, 120:].mean()


def test_row_framing_keeps_one_scale_per_row(tmp_path):
    small, big = trimesh.creation.box(extents=(1, 1, 1)), trimesh.creation.box(extents=(2, 2, 2))
    render_grid([[small, big]], tmp_path / "cell.png", cell=(120, 100))
    render_grid([[small, big]], tmp_path / "row.png", cell=(120, 100), frame="row")
    cell_small, cell_big = _coverage(tmp_path / "cell.png")
    row_small, row_big = _coverage(tmp_path / "row.png")
    assert abs(cell_small - cell_big) < 0.02  # each fitted to its own cell
    assert row_small < 0.5 * row_big          # one camera: the small box looks small
    with pytest.raises(ValueError, match="frame"):
        render_grid([[small]], tmp_path / "x.png", frame="column")
