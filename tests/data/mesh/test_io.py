"""Mesh loading (formats, scenes, resources), validation errors, normalisation."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import load_mesh, normalize, resolve_mesh_path

from ...helpers import PLY_TRIANGLE_HEADER


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "off", "glb"])
def test_loads_each_format(tmp_path, ext):
    box = trimesh.creation.box(extents=[2.0, 1.0, 0.5])
    path = tmp_path / f"box.{ext}"
    box.export(path)
    mesh = load_mesh(path)
    assert isinstance(mesh, trimesh.Trimesh)
    assert mesh.faces.shape == (12, 3) and mesh.faces.dtype == np.int64
    np.testing.assert_allclose(mesh.bounds, box.bounds, atol=1e-6)


def test_scene_is_concatenated_with_transforms(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), transform=trimesh.transformations.translation_matrix([5, 0, 0]))
    scene.add_geometry(trimesh.creation.icosphere(subdivisions=1))
    path = tmp_path / "two.glb"
    scene.export(path)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 12 + 80
    assert mesh.bounds[1, 0] == pytest.approx(5.5, abs=1e-5)


def test_pyvista_resource_is_read_from_the_installed_package():
    folder = Path(importlib.util.find_spec("pyvista").origin).parent / "examples"
    assert resolve_mesh_path("pyvista:ant.ply") == folder / "ant.ply"
    mesh = load_mesh("pyvista:ant.ply")
    assert mesh.faces.shape == (912, 3) and mesh.vertices.shape == (486, 3)


@pytest.mark.parametrize("spec, words", [("pyvista:nope.ply", ["nope.ply", "ant.ply"]),
                                         ("pyvista:../x.ply", ["plain file name"])])
def test_bad_resource(spec, words):
    with pytest.raises(DataError) as e:
        load_mesh(spec)
    for w in words:
        assert w in str(e.value)


def test_relative_path_resolves_against_base_dir(tmp_path):
    assert resolve_mesh_path("a/b.ply", tmp_path) == tmp_path / "a" / "b.ply"
    assert resolve_mesh_path(str(tmp_path / "c.ply"), "/elsewhere") == tmp_path / "c.ply"


def _write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name, text, words", [
    ("missing.ply", None, ["not found"]),
    ("garbage.ply", "\x00\x01 not a mesh", ["could not read"]),
    ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", ["no triangles"]),
    ("empty.obj", "", ["no triangles"]),
    ("nan.ply", PLY_TRIANGLE_HEADER + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", ["NaN", "vertex 1"]),
    ("inf.ply", PLY_TRIANGLE_HEADER + "0 0 0\n1 0 0\n0 1 inf\n3 0 1 2\n", ["NaN or infinite"]),
    ("range.ply", PLY_TRIANGLE_HEADER + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", ["face indices", "3 vertices"]),
])
def test_bad_meshes_raise_dataerror_naming_the_file(tmp_path, name, text, words):
    path = tmp_path / name if text is None else _write(tmp_path, name, text)
    with pytest.raises(DataError) as e:
        load_mesh(path)
    message = str(e.value)
    assert name in message and "Fix:" in message
    for w in words:
        assert w in message


def test_normalize_fits_bounding_box_and_inverts():
    rng = np.random.default_rng(0)
    mesh = trimesh.Trimesh(rng.normal(size=(50, 3)) * [3.0, 1.0, 0.5] + [10, -2, 7],
                           rng.integers(0, 50, (40, 3)), process=False)
    out, center, scale = normalize(mesh, bound=0.8)
    lo, hi = out.vertices.min(0), out.vertices.max(0)
    np.testing.assert_allclose(lo + hi, 0.0, atol=1e-12)  # centred
    assert (hi - lo).max() == pytest.approx(1.6)  # longest side spans 2 * bound
    assert np.all(hi <= 0.8 + 1e-12) and np.all(lo >= -0.8 - 1e-12)
    np.testing.assert_allclose(out.vertices / scale + center, mesh.vertices, atol=1e-12)
    np.testing.assert_array_equal(out.faces, mesh.faces)
    assert mesh.vertices.max() > 1.0  # input untouched


def test_normalize_rejects_degenerate_mesh():
    mesh = trimesh.Trimesh(np.ones((3, 3)), [[0, 1, 2]], process=False)
    with pytest.raises(DataError, match="coincide"):
        normalize(mesh)
