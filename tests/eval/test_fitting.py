import math

import numpy as np
import pytest
import trimesh

from ngc_gen.eval import (chamfer, emd, mesh_chamfer, point_mesh_distance,
                          reconstruction_metrics, sample_surface, volume_area_change)
from ngc_gen.eval.fitting import point_triangle_distance2

KEYS = {"cd", "hd", "emd", "cd_l1", "fscore", "normal_consistency", "volume", "area",
        "gt_volume", "gt_area", "empty"}


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=4)


def test_sample_surface_shapes_and_determinism(sphere):
    p, n = sample_surface(sphere, 1000, seed=3)
    assert p.shape == (1000, 3) and n.shape == (1000, 3)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    assert np.all(np.linalg.norm(p, axis=1) <= 1.0 + 1e-9)  # on the inscribed polyhedron
    p2, n2 = sample_surface(sphere, 1000, seed=3)
    assert np.array_equal(p, p2) and np.array_equal(n, n2)
    p3, _ = sample_surface(sphere, 1000, seed=4)
    assert not np.array_equal(p, p3)


def test_sample_surface_is_area_weighted():
    # two disjoint cubes of areas 6 and 24: 4/5 of the samples belong on the big one
    small = trimesh.creation.box(extents=[1, 1, 1])
    big = trimesh.creation.box(extents=[2, 2, 2])
    big.apply_translation([5, 0, 0])
    both = trimesh.util.concatenate([small, big])
    p, _ = sample_surface(both, 20_000, seed=0)
    frac_big = np.mean(p[:, 0] > 2.5)
    assert frac_big == pytest.approx(4 / 5, abs=0.01)


def test_identical_meshes_are_zero(sphere):
    m = reconstruction_metrics(sphere, sphere.copy(), seed=0, n_emd=512)
    assert KEYS <= set(m)
    assert m["cd"] == 0.0 and m["hd"] == 0.0 and m["emd"] == 0.0 and m["cd_l1"] == 0.0
    assert m["fscore"] == 1.0
    assert m["normal_consistency"] == pytest.approx(1.0)
    assert m["volume"] == pytest.approx(m["gt_volume"]) and m["area"] == pytest.approx(m["gt_area"])
    assert m["empty"] is False and m["watertight"] and m["gt_watertight"]


def test_scaled_sphere(sphere):
    s = 1.01
    big = sphere.copy().apply_scale(s)
    m = reconstruction_metrics(big, sphere, seed=0, n_emd=512)
    eps = s - 1.0
    assert m["cd"] == pytest.approx(2 * eps ** 2, rel=0.05)
    assert m["hd"] == pytest.approx(eps, rel=0.05)
    assert m["cd_l1"] == pytest.approx(eps, rel=0.05)
    assert m["emd"] == pytest.approx(eps, rel=0.05)
    assert m["normal_consistency"] > 0.99
    # at tau well below the 0.01 offset nothing matches
    tight = reconstruction_metrics(big, sphere, seed=0, n_emd=256, fscore_tau=0.005)
    assert tight["fscore"] == 0.0


def test_fscore_threshold(sphere):
    big = sphere.copy().apply_scale(1.05)
    m = reconstruction_metrics(big, sphere, seed=0, n_emd=256, fscore_tau=0.01)
    assert m["fscore"] == 0.0
    m = reconstruction_metrics(big, sphere, seed=0, n_emd=256, fscore_tau=0.1)
    assert m["fscore"] == 1.0


def test_translation_increases_cd_monotonically(sphere):
    shifts = [0.0, 0.01, 0.03, 0.1, 0.3]
    res = [reconstruction_metrics(sphere.copy().apply_translation([d, 0, 0]), sphere,
                                  n_chamfer=5000, n_emd=256) for d in shifts]
    for key in ("cd", "hd", "emd", "cd_l1"):
        vals = [r[key] for r in res]
        assert all(a < b for a, b in zip(vals, vals[1:])), (key, vals)
    fs = [r["fscore"] for r in res]
    assert all(a >= b for a, b in zip(fs, fs[1:])) and fs[0] == 1.0 and fs[-1] < 0.2


def test_determinism(sphere):
    other = trimesh.creation.icosphere(subdivisions=3).apply_scale([1.1, 0.9, 1.0])
    a = reconstruction_metrics(other, sphere, seed=7, n_chamfer=5000, n_emd=256)
    b = reconstruction_metrics(other, sphere, seed=7, n_chamfer=5000, n_emd=256)
    c = reconstruction_metrics(other, sphere, seed=8, n_chamfer=5000, n_emd=256)
    assert a == b
    assert a["cd"] != c["cd"]


def test_emd_of_shifted_set_is_shift_length():
    rng = np.random.default_rng(0)
    p = rng.uniform(-1, 1, size=(512, 3))
    v = np.array([0.03, -0.02, 0.05])
    assert emd(p, p + v) == pytest.approx(np.linalg.norm(v), rel=1e-9)
    assert emd(p, rng.permutation(p)) == 0.0
    with pytest.raises(ValueError):
        emd(p, p[:10])


def test_emd_and_chamfer_by_hand():
    # both points of b sit on a[0]: EMD must send one of them to a[1] (mean 1/2); squared
    # Chamfer = mean over a (0 + 1)/2 + mean over b 0.
    a = np.array([[0.0, 0, 0], [1.0, 0, 0]])
    b = np.array([[0.0, 0, 0], [0.0, 0, 0]])
    assert emd(a, b) == pytest.approx(0.5)
    assert chamfer(a, b) == pytest.approx(0.5)


def test_empty_prediction_does_not_crash(sphere):
    m = reconstruction_metrics(trimesh.Trimesh(), sphere)
    assert m["empty"] is True
    assert math.isinf(m["cd"]) and math.isinf(m["hd"]) and math.isinf(m["emd"])
    assert m["fscore"] == 0.0 and math.isnan(m["normal_consistency"])
    assert m["area"] == 0.0 and m["gt_area"] == pytest.approx(sphere.area)
    with pytest.raises(ValueError):
        reconstruction_metrics(sphere, trimesh.Trimesh())


@pytest.mark.parametrize("s", [0.8, 1.1, 1.5])
def test_volume_area_change_of_scaled_sphere(sphere, s):
    r = volume_area_change(sphere, sphere.copy().apply_scale(s))
    assert r["eps_v"] == pytest.approx(abs(s ** 3 - 1), rel=1e-9)
    assert r["eps_a"] == pytest.approx(abs(s ** 2 - 1), rel=1e-9)
    assert volume_area_change(sphere, sphere.copy()) == {"eps_v": 0.0, "eps_a": 0.0}


def test_point_mesh_distance_is_exact(sphere):
    rng = np.random.default_rng(0)
    p = rng.normal(size=(300, 3)) * 1.5
    tris = sphere.vertices[sphere.faces]
    brute = np.sqrt(np.stack([point_triangle_distance2(
        np.broadcast_to(q[None, None], (1, len(tris), 3)), tris[None]).min() for q in p]))
    np.testing.assert_allclose(point_mesh_distance(p, sphere, k=4), brute, rtol=0, atol=1e-12)
    # a triangle's own vertex, an edge midpoint and its plane above the centroid
    a, b, c = tris[0]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    d = point_triangle_distance2(np.array([[a, (a + b) / 2, (a + b + c) / 3 + 0.01 * n]]),
                                 np.broadcast_to(tris[0], (1, 3, 3, 3)))
    np.testing.assert_allclose(d[0], [0.0, 0.0, 1e-4], atol=1e-15)


def test_mesh_chamfer_is_zero_for_one_surface_and_sees_real_differences(sphere):
    """The DeepSDF sample estimator moves with every face (one face removed: ~1e-5); the
    surface version is 0 for equal surfaces and small for a missing face."""
    assert mesh_chamfer(sphere, sphere.copy()) == 0.0
    fewer = trimesh.Trimesh(sphere.vertices, sphere.faces[1:], process=False)
    sample_cd = chamfer(sample_surface(fewer, 30000, 0)[0], sample_surface(sphere, 30000, 0)[0])
    assert sample_cd > 1e-6                               # the noise of the sample estimator
    assert 0 < mesh_chamfer(fewer, sphere) < 1e-7
    bigger = sphere.copy()
    bigger.vertices *= 1.01                               # 0.01 apart: 2 x 1e-4 summed
    assert mesh_chamfer(bigger, sphere) == pytest.approx(2e-4, rel=0.05)


def test_fragments_count_small_components_only(sphere):
    from ngc_gen.eval import component_sizes, fragments

    speck = trimesh.creation.icosphere(subdivisions=0, radius=0.01)  # 20 faces, under 1% of the 10300
    twin = sphere.copy().apply_translation([3, 0, 0])
    parts = [sphere, twin] + [speck.copy().apply_translation([0, 0, 2 + i]) for i in range(3)]
    mesh = trimesh.util.concatenate(parts)
    assert list(component_sizes(mesh)) == [len(sphere.faces)] * 2 + [20] * 3
    assert fragments(mesh) == 3 and fragments(mesh, fraction=0.001) == 0
    assert fragments(trimesh.util.concatenate([sphere, twin])) == 0  # two big parts are no bits
    # a triangle soup (every face with its own vertices) is one piece, not one per face
    soup = trimesh.Trimesh(sphere.vertices[sphere.faces].reshape(-1, 3),
                           np.arange(3 * len(sphere.faces)).reshape(-1, 3), process=False)
    assert fragments(soup) == 0 and list(component_sizes(soup)) == [len(sphere.faces)]
    m = reconstruction_metrics(mesh, sphere, seed=0, n_chamfer=2000, n_emd=64)
    assert m["fragments"] == 3 and m["gt_fragments"] == 0


def _two_spheres():
    """Spheres of radius 0.3 at x = -+0.15, concatenated: watertight, a quarter of each inside
    the other (the size of a part in the normalised frame, where F@0.01 means something)."""
    a = trimesh.creation.icosphere(subdivisions=4, radius=0.3).apply_translation([-0.15, 0, 0])
    b = trimesh.creation.icosphere(subdivisions=4, radius=0.3).apply_translation([0.15, 0, 0])
    return a, b, trimesh.util.concatenate([a, b])


def test_sample_boundary_drops_faces_inside_other_pieces():
    from ngc_gen.eval import sample_boundary

    a, b, union = _two_spheres()
    assert union.is_watertight
    p, n = sample_boundary(union, 4000, seed=1)
    assert p.shape == (4000, 3) and n.shape == (4000, 3)
    # every sample is outside the other sphere (up to the polyhedron's sag), i.e. on the boundary
    inside_other = (np.linalg.norm(p - [-0.15, 0, 0], axis=1) < 0.297) & (
        np.linalg.norm(p - [0.15, 0, 0], axis=1) < 0.297)
    assert not inside_other.any()
    # nothing to drop: exactly sample_surface
    single = trimesh.creation.icosphere(subdivisions=3)
    assert np.array_equal(sample_boundary(single, 500, 2)[0], sample_surface(single, 500, 2)[0])
    p2, _ = sample_boundary(union, 4000, seed=1)
    assert np.array_equal(p, p2)


def test_union_of_pieces_scored_on_its_boundary():
    # the union's own boundary (faces outside the other sphere) against the two overlapping
    # spheres: a perfect fit of the solid scores as one, not as a fit missing the inner caps
    a, b, union = _two_spheres()
    keep_a = np.linalg.norm(a.triangles_center - [0.15, 0, 0], axis=1) > 0.3
    keep_b = np.linalg.norm(b.triangles_center - [-0.15, 0, 0], axis=1) > 0.3
    outer = trimesh.util.concatenate([a.submesh([np.flatnonzero(keep_a)], append=True),
                                      b.submesh([np.flatnonzero(keep_b)], append=True)])
    m = reconstruction_metrics(outer, union, seed=0, n_emd=256)
    assert m["fscore"] > 0.99 and m["normal_consistency"] > 0.99 and m["cd"] < 1e-4
    # the same mesh scored against samples that include the inner caps loses ~1/4 recall
    g, _ = sample_surface(union, 30_000, 0)
    p, _ = sample_surface(outer, 30_000, 0)
    from ngc_gen.eval import fscore
    assert fscore(p, g) < 0.9


def test_fscore_and_nc_measure_the_surface_not_the_sample_spacing():
    # one surface, two tessellations (every face split in four): the samples differ, the
    # surface does not. 30k samples on area 8 are ~0.016 apart, wider than tau = 0.01
    gt = trimesh.creation.icosphere(subdivisions=4, radius=0.8)
    pred = gt.subdivide()
    m = reconstruction_metrics(pred, gt, seed=0, n_emd=256)
    assert m["fscore"] == 1.0 and m["normal_consistency"] == pytest.approx(1.0, abs=1e-9)
    assert m["fscore_samples"] < 0.95
