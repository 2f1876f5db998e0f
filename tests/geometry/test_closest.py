"""The foot point of `to_relative` is the global closest point of the curve, checked against
a brute force (ngc_gen.geometry.closest_check, which bench/geometry.py reports too)."""
import numpy as np
import torch

from ngc_gen.geometry.closest_check import (closest_point_check, nearest_sample,
                                            random_bezier_gc)
from ngc_gen.geometry.relative_tables import coarse_owned, coarse_reach


def test_foot_point_is_the_global_closest_point():
    """>= 1e5 points inside random Bezier GCs of degrees 1-5, radii up to the curvature limit,
    tubes that overlap themselves, points nearly equidistant from two arcs (some within the
    window the kernel certifies around its local foot point): no foot point is farther than
    the nearest of 458,752 curve samples polished by Newton. Fails with the global search
    switched off (the nearest coarse vertex's window alone: 3.8e-2 farther) and with the
    certificate's radius 10x too wide (4.8e-4, on a "neck" GC)."""
    r = closest_point_check()
    assert r["closest_point_points"] >= 100_000
    assert r["closest_point_equidistant_points"] >= 2_000
    assert r["closest_point_gcs_at_curvature_limit"] >= 10
    assert r["closest_point_excess_max"] <= 1e-9, r
    assert r["closest_point_excess_min"] >= -1e-9, r  # the reference is the closest point too


def test_reference_finds_the_nearest_sample(rng):
    """The reference's pruned search returns the exhaustive nearest sample."""
    gc = random_bezier_gc(rng, 4, "crossing")
    n = 3 * 4096
    X = gc.curve.evaluate(torch.linspace(0, 1, n, dtype=torch.float64))[0]
    q = torch.as_tensor(rng.uniform(-0.6, 0.6, (3000, 3)))
    i = nearest_sample(gc.curve, q, n, levels=(4096, 256, 16, 1))
    d = torch.cdist(q, X)
    np.testing.assert_allclose(d.gather(1, i[:, None])[:, 0], d.min(1).values, rtol=0,
                               atol=1e-15)


def test_segment_and_coarse_bounds_hold_the_arc(rng):
    """Each segment's arc lies within its bulge of the chord, and each coarse vertex's ball
    holds the arcs of its segments (what lets the kernel skip them)."""
    for degree in (2, 3, 5):
        gc = random_bezier_gc(rng, degree, "box")
        T = gc.tables
        K = gc.segments
        t = (np.arange(K)[:, None] + np.linspace(0, 1, 65)[None]) / K  # (K, 65)
        C = gc.curve.evaluate(gc.arc.s_of_t(torch.as_tensor(t.reshape(-1))))[0].numpy()
        C = C.reshape(K, 65, 3)
        A, B = T.poly_x[:-1, None], T.poly_x[1:, None]
        lam = np.clip(((C - A) * (B - A)).sum(-1) / ((B - A) ** 2).sum(-1), 0, 1)
        off = np.linalg.norm(A + lam[..., None] * (B - A) - C, axis=-1).max(1)
        assert np.all(off <= T.bulge) and np.all(T.bulge < 2 * off + 1e-9)
        for c in range(len(T.coarse)):
            arc = C[T.owned[c]:T.owned[c + 1]].reshape(-1, 3)
            assert np.linalg.norm(arc - T.poly_x[T.coarse[c]], axis=1).max() <= T.reach[c]
        np.testing.assert_array_equal(T.owned, coarse_owned(T.coarse))
        np.testing.assert_allclose(T.reach, coarse_reach(T.poly_x, T.bulge, T.coarse,
                                                          T.owned))

