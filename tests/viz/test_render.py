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


def _cells(path, cell, n_rows, n_cols):
    from PIL import Image

    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    drawn = np.abs(img - 255).sum(-1) > 30
    w, h = cell
    return [drawn[i * h:(i + 1) * h, j * w:(j + 1) * w] for i in range(n_rows)
            for j in range(n_cols)]


def _rod(axis: int, length: float = 2.0) -> trimesh.Trimesh:
    rod = trimesh.creation.cylinder(radius=length / 20, height=length)  # 10:1 along z
    if axis != 2:
        rod.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], np.eye(3)[axis]))
    return rod


@pytest.mark.parametrize("frame", ["cell", "row"])
def test_long_tall_and_flat_shapes_fit_whole_in_their_cells(tmp_path, frame):
    """A 10:1 rod along x, y and z (tall), a plate and a cube: no drawn pixel on any cell's
    edge, and each shape spans most of its cell's width or height (not a speck)."""
    cell = (160, 120)
    rows = [[_rod(0), _rod(1), _rod(2)],
            [trimesh.creation.box(extents=(3.0, 2.0, 0.1)), trimesh.creation.box(),
             _rod(2, length=6.0)]]
    out = render_grid(rows, tmp_path / "grid.png", cell=cell, frame=frame)
    spans = []
    for k, c in enumerate(_cells(out, cell, 2, 3)):
        assert c.any(), k
        edge = np.concatenate([c[0], c[-1], c[:, 0], c[:, -1]])
        assert not edge.any(), f"cell {k} is cut at its edge"
        ys, xs = np.nonzero(c)
        spans.append(max((np.ptp(xs) + 1) / cell[0], (np.ptp(ys) + 1) / cell[1]))
    spans = np.reshape(spans, (2, 3))
    # each cell fitted to its shape, or (one scale per row) to the row's largest
    assert (spans if frame == "cell" else spans.max(1)).min() > 0.75, spans


def test_a_y_up_mesh_is_drawn_standing(tmp_path):
    """A tall rod along y, drawn with up=y (or detected: it stands on a foot plate), is upright
    in the picture: taller than wide; with up=z it lies."""
    foot = trimesh.creation.box(extents=(1.0, 0.05, 1.0), transform=trimesh.transformations
                                .translation_matrix((0, -1.0, 0)))
    rod = trimesh.util.concatenate([_rod(1), foot])
    cell = (160, 120)
    shapes = {}
    for up in ("y", "auto", "z"):
        out = render_grid([[rod]], tmp_path / f"{up}.png", cell=cell, up=up)
        c = _cells(out, cell, 1, 1)[0]
        ys, xs = np.nonzero(c)
        shapes[up] = (np.ptp(ys) + 1) / (np.ptp(xs) + 1)
    assert shapes["y"] > 1.5 and shapes["auto"] > 1.5, shapes
    assert shapes["z"] < 1.0, shapes


def test_gc_names_are_spread_so_no_two_overlap():
    from ngc_gen.viz.render import label_boxes, spread_labels

    rng = np.random.default_rng(0)
    texts = [f"leg_{s}{i}" for s in "lr" for i in range(1, 4)] + ["head", "thorax", "abdomen",
                                                                 "antenna_l", "antenna_r"]
    xy = np.array([320.0, 280.0]) + rng.normal(0, 6, (len(texts), 2))  # a cluster of names
    xy[0] = [40.0, 40.0]                                                  # and one far away
    sizes = label_boxes(texts)
    out = spread_labels(xy, sizes, 640.0, 560.0)
    assert np.allclose(out[0], xy[0])  # a free label stays on its point
    for i in range(len(texts)):
        assert np.all(out[i] - sizes[i] / 2 >= 0) and np.all(out[i] + sizes[i] / 2 <= [640, 560])
        for j in range(i):
            gap = np.abs(out[i] - out[j]) - (sizes[i] + sizes[j]) / 2
            assert gap.max() >= 0, (texts[i], texts[j])  # apart along x or y
