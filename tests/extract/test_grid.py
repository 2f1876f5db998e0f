import numpy as np
import pytest

from ngc_gen.extract.grid import Grid, lattice_points, restrict, slabs


def test_index_box_covers_every_grid_point_in_the_world_box():
    rng = np.random.default_rng(0)
    g = Grid(37, 0.9)
    x = g.axis()
    for _ in range(50):
        lo = rng.uniform(-1.2, 0.8, 3)
        hi = lo + rng.uniform(0.0, 1.0, 3)
        box = g.index_box(lo, hi)
        inside = [(x >= lo[d]) & (x <= hi[d]) for d in range(3)]
        if not all(m.any() for m in inside):
            continue
        first, last = box
        for d in range(3):
            idx = np.nonzero(inside[d])[0]
            assert first[d] <= idx.min() and idx.max() <= last[d]
            assert first[d] >= idx.min() - 2 and last[d] <= idx.max() + 2  # small slack
    assert g.index_box([1.5, 0, 0], [2.0, 1, 1]) is None


def test_lattice_points_match_flat_index_and_slabs_partition():
    g = Grid(9, 1.0)
    lat = restrict(g.full(), (np.array([1, 0, 3]), np.array([6, 8, 5])))
    seen = []
    for slab in slabs(lat, 40):
        pts, flat = lattice_points(g, slab)
        i, j, k = np.unravel_index(flat.numpy(), (9, 9, 9))
        x = g.axis()
        assert np.array_equal(pts.numpy(), np.stack([x[i], x[j], x[k]], 1))
        seen.append(flat.numpy())
    seen = np.concatenate(seen)
    assert len(seen) == 6 * 9 * 3 == len(np.unique(seen))


def test_grid_rejects_bad_arguments():
    with pytest.raises(ValueError, match="resolution"):
        Grid(1)
    with pytest.raises(ValueError, match="bound"):
        Grid(8, -1.0)
