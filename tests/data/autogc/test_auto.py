"""Automatic single GC: encloses real meshes, follows the principal axis, stays reasonably tight."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation, auto_gc
from ngc_gen.data.mesh.io import load_mesh, normalize
from ngc_gen.data.mesh.sampling import sample_surface


@pytest.mark.parametrize("spec", ["pyvista:ant.ply", "pyvista:airplane.ply"])
def test_encloses_every_vertex_and_surface_point_of_real_meshes(spec):
    mesh, _, _ = normalize(load_mesh(spec))
    gc = auto_gc(mesh)
    assert np.all(gc.contains(mesh.vertices))
    surface, _ = sample_surface(mesh.vertices, mesh.faces, 20_000, np.random.default_rng(0))
    assert np.all(gc.contains(surface))


def test_follows_principal_axis_of_a_rotated_slab():
    R = Rotation.from_euler("xyz", [30, -50, 70], degrees=True).as_matrix()
    box = trimesh.creation.box(extents=[2.0, 0.4, 0.2])
    box.apply_transform(np.block([[R, np.array([[0.1], [0.2], [-0.3]])], [np.zeros((1, 3)), np.ones((1, 1))]]))
    gc = auto_gc(box)
    assert np.all(gc.contains(box.vertices))
    d = gc.to_dict()
    p0, p1 = np.array(d["curve"]["points"])
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    assert abs(axis @ R[:, 0]) > 0.999  # along the long side
    ry, rz = d["keys"][0]["radii"]
    assert ry / rz == pytest.approx(2.0, rel=0.1)  # elliptic profile follows the 0.4 x 0.2 section
    # tight: its volume (tube + two half ellipsoids) within 2x the box's volume of 0.16
    volume = np.pi * ry * rz * (gc.length + 2.0 / 3.0 * sum(d["caps"]))
    assert 0.16 < volume < 0.32


def test_flat_mesh_gets_positive_radii():
    square = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0.5, 0], [0, 0.5, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    gc = auto_gc(square)
    assert min(gc.to_dict()["keys"][0]["radii"]) > 0
    assert np.all(gc.contains(square.vertices))


def test_auto_annotation_is_deterministic_and_named():
    axis = AutoGCSettings.from_yaml(method="axis")
    a, b = (auto_annotation("pyvista:ant.ply", settings=axis) for _ in range(2))
    assert a.name == "ant" and a.mesh == "pyvista:ant.ply" and a.bound == 0.8
    assert a.to_dict() == b.to_dict()
