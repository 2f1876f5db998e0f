"""Signed distance: accuracy and sign against analytic shapes, robustness to holes."""

from __future__ import annotations

import numpy as np
import torch
import trimesh

from ngc_gen.data.mesh.sdf import signed_distance, solid_surface


def box_sdf(p: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Exact SDF of an axis-aligned box centred at 0 with half extents ``half``."""
    q = np.abs(p) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def test_box_sdf_is_exact():
    half = np.array([0.5, 0.3, 0.2])
    box = trimesh.creation.box(extents=2 * half)
    p = np.random.default_rng(0).uniform(-1, 1, (20_000, 3))
    d = signed_distance(p, box.vertices, box.faces)
    expected = box_sdf(p, half)
    np.testing.assert_allclose(d, expected, atol=1e-9)
    assert (d < 0).sum() == (expected < 0).sum() > 100  # inside points exist and are negative


def test_sphere_sdf_sign_and_accuracy():
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.5)
    p = np.random.default_rng(1).uniform(-1, 1, (20_000, 3))
    d = signed_distance(p, sphere.vertices, sphere.faces)
    expected = np.linalg.norm(p, axis=1) - 0.5
    np.testing.assert_allclose(np.abs(d), np.abs(expected), atol=1e-3)  # faceting error ~1e-4
    far = np.abs(expected) > 5e-3
    np.testing.assert_array_equal(np.sign(d[far]), np.sign(expected[far]))


def test_sign_survives_holes():
    """Winding-number sign: a sphere with missing faces still has a correct inside."""
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    keep = np.random.default_rng(2).random(len(sphere.faces)) > 0.05
    p = np.random.default_rng(3).uniform(-1, 1, (5_000, 3))
    r = np.linalg.norm(p, axis=1)
    d = signed_distance(p, sphere.vertices, sphere.faces[keep])
    assert np.all(d[r < 0.4] < 0) and np.all(d[r > 0.6] > 0)


def test_chunking_and_torch_input_match_one_call():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    p = np.random.default_rng(4).uniform(-1, 1, (2_500, 3))
    whole = signed_distance(p, sphere.vertices, sphere.faces)
    np.testing.assert_array_equal(signed_distance(p, sphere.vertices, sphere.faces, chunk_size=1000), whole)
    from_torch = signed_distance(torch.from_numpy(p).float(), sphere.vertices, sphere.faces)
    assert from_torch.shape == (2_500,) and from_torch.dtype == np.float64
    np.testing.assert_allclose(from_torch, whole, atol=1e-6)


def test_sign_inside_intersecting_pieces():
    """Two overlapping closed spheres in one mesh (like pyvista's ant): inside either is negative."""
    a = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    b = a.copy()
    b.apply_translation([0.6, 0, 0])
    both = trimesh.util.concatenate([a, b])
    p = np.array([[0.0, 0, 0], [0.3, 0, 0], [0.6, 0, 0], [1.3, 0, 0], [-0.7, 0, 0]])
    d = signed_distance(p, both.vertices, both.faces)
    np.testing.assert_array_equal(d < 0, [True, True, True, False, False])


def test_the_solids_distance_has_no_valley_at_faces_inside_another_piece():
    """Two intersecting closed boxes in one mesh: the faces of each inside the other are no
    surface of the solid. Every triangle's distance falls to 0 on them (a fit then cracks
    there); the solid's distance (`solid_surface`) is the union's: exact outside (the min of
    the boxes' SDFs), inside at least as deep as the deeper box says (up to the size the
    crossing faces are split to), and a mesh without inner faces is left as it is."""
    a = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    b = trimesh.creation.box(extents=(0.6, 0.6, 0.6))
    b.apply_translation([0.5, 0.1, 0.05])
    both = trimesh.util.concatenate([a, b])
    sv, sf = solid_surface(both.vertices, both.faces)
    rng = np.random.default_rng(0)
    p = rng.uniform(-0.7, 0.9, (4000, 3))
    exact = np.minimum(box_sdf(p, np.full(3, 0.5)),
                       box_sdf(p - [0.5, 0.1, 0.05], np.full(3, 0.3)))
    solid = signed_distance(p, both.vertices, both.faces, distance_mesh=(sv, sf))
    every = signed_distance(p, both.vertices, both.faces)
    out = exact > 0
    np.testing.assert_allclose(solid[out], exact[out], atol=1e-6)
    edge = 2.5e-3 * np.linalg.norm(np.ptp(both.vertices, axis=0))   # the split's size
    assert (solid[~out] <= exact[~out] + edge).all() and (solid[~out] < 0).all()
    assert (every[~out] > exact[~out] + 0.01).any()           # the valley the fix removes
    inner = np.array([[0.5, 0.1, 0.05], [0.3, 0.1, 0.05]])   # on a buried face, and near one
    assert every[0] > -1e-9 and (signed_distance(inner, both.vertices, both.faces,
                                                 distance_mesh=(sv, sf)) < -0.1).all()
    v, f = solid_surface(a.vertices, a.faces)
    assert v is not None and np.array_equal(f, a.faces)
