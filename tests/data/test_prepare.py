"""Data preparation: samples, SDF, relative-coordinate pairs, coverage check and the npz cache."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest
import trimesh
import yaml

from ngc_gen.data import prepare as prepare_module
from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.data.prepare import PrepareSettings, cache_path, load_prepared, prepare_shape
from ngc_gen.geometry import GeneralizedCylinder

from ..helpers import PLY_TRIANGLE_HEADER

SMALL = PrepareSettings.from_yaml(n_samples=5_000, coverage_samples=5_000)


@pytest.fixture
def cache(tmp_path):
    return tmp_path / "cache"


def test_arrays_sdf_and_pairs(sphere_annotation, cache):
    shape = prepare_shape(sphere_annotation, SMALL, cache)
    M, n_surface = 5_000, 3_500
    assert shape.points.shape == (M, 3) and shape.points.dtype == np.float32
    assert shape.sdf.shape == (M,) and shape.sdf.dtype == np.float32
    assert shape.n_surface == n_surface and shape.coverage == 1.0 and shape.gc_names == ["body"]
    assert shape.pair_point.dtype == np.int64 and shape.pair_gc.dtype == np.int64
    assert shape.pair_rel.shape == (len(shape.pair_point), 3) and shape.pair_rel.dtype == np.float32
    # SDF of the (faceted) unit sphere scaled to radius 0.8: |p| - 0.8 up to the faceting error
    r = np.linalg.norm(shape.points.astype(np.float64), axis=1)
    np.testing.assert_allclose(shape.sdf, r - 0.8, atol=4e-3)
    near = shape.sdf[:n_surface]
    assert 0.006 < np.abs(near).mean() < 0.01  # offsets N(0, 0.01): E|x| = 0.008
    # every volume sample lies in the GC, and the pairs' relative coords map back to the samples
    assert np.all(np.isin(np.arange(n_surface, M), shape.pair_point))
    gc = shape.gcs()[0]
    assert np.all(GeneralizedCylinder.inside_relative(shape.pair_rel.astype(np.float64)))
    np.testing.assert_allclose(gc.to_world(shape.pair_rel.astype(np.float64)),
                               shape.points[shape.pair_point], atol=1e-4)
    # the normalised mesh and its transform are stored
    assert shape.mesh_vertices.shape == (2562, 3) and shape.mesh_faces.shape == (5120, 3)
    assert shape.scale == pytest.approx(0.8) and np.allclose(shape.center, 0.0)


def test_sample_in_k_gcs_has_k_pairs(sphere_file, write_yaml, gc_dict, cache):
    path = write_yaml({"name": "two", "mesh": sphere_file.name,
                       "gcs": [gc_dict("left", -0.6, 0.1), gc_dict("right", -0.1, 0.6)]})
    shape = prepare_shape(path, SMALL, cache)
    gcs = shape.gcs()
    expected = sum(np.asarray(g.contains(shape.points.astype(np.float64)), dtype=int) for g in gcs)
    np.testing.assert_array_equal(np.bincount(shape.pair_point, minlength=len(shape.points)), expected)
    assert (expected == 2).sum() > 300
    for g, gc in enumerate(gcs):
        sel = shape.pair_gc == g
        np.testing.assert_allclose(gc.to_world(shape.pair_rel[sel].astype(np.float64)),
                                   shape.points[shape.pair_point[sel]], atol=1e-4)


def test_volume_samples_are_uniform_over_the_union(sphere_file, write_yaml, gc_dict, cache):
    """A small GC nested in a big one must not double the sample density where they overlap."""
    big, small = gc_dict("big", -0.3, 0.3, (0.9, 0.9), (0.8, 0.8)), gc_dict("small", -0.1, 0.1, (0.3, 0.3), (0.2, 0.2))
    path = write_yaml({"name": "nested", "mesh": sphere_file.name, "gcs": [big, small]})
    settings = dataclasses.replace(SMALL, surface_fraction=0.0, n_samples=10_000,
                                   shell_fraction=0.0)
    shape = prepare_shape(path, settings, cache)

    def volume(d):
        ry, rz = d["keys"][0]["radii"]
        length = d["curve"]["points"][1][0] - d["curve"]["points"][0][0]
        return np.pi * ry * rz * (length + 2.0 / 3.0 * sum(d["caps"]))

    p = volume(small) / volume(big)  # uniform: P(in small) = vol(small) / vol(union = big)
    frac = np.isin(np.arange(10_000), shape.pair_point[shape.pair_gc == 1]).mean()
    assert abs(frac - p) < 4 * np.sqrt(p * (1 - p) / 10_000)


def test_deterministic_for_a_seed(sphere_annotation):
    a, b = prepare_shape(sphere_annotation, SMALL), prepare_shape(sphere_annotation, SMALL)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.pair_rel, b.pair_rel)
    c = prepare_shape(sphere_annotation, dataclasses.replace(SMALL, seed=1))
    assert not np.array_equal(a.points, c.points)


def test_cache_is_reused(sphere_annotation, cache, monkeypatch):
    first = prepare_shape(sphere_annotation, SMALL, cache)
    assert first.path == cache_path(cache, "sphere") and not first.from_cache
    mtime = first.path.stat().st_mtime_ns

    def fail(*args, **kwargs):
        raise AssertionError("re-prepared an unchanged shape")

    monkeypatch.setattr(prepare_module, "compute_prepared", fail)
    second = prepare_shape(sphere_annotation, SMALL, cache)
    assert second.from_cache and second.path.stat().st_mtime_ns == mtime
    assert second.key == first.key
    np.testing.assert_array_equal(second.points, first.points)
    np.testing.assert_array_equal(second.pair_point, first.pair_point)
    assert second.annotation().to_dict() == load_annotation(sphere_annotation).to_dict()
    assert os.listdir(cache) == ["sphere.npz"]  # one file per shape, no temp files


def test_cache_invalidation(sphere_annotation, sphere_file, cache):
    key = prepare_shape(sphere_annotation, SMALL, cache).key
    changed = prepare_shape(sphere_annotation, dataclasses.replace(SMALL, seed=7), cache)
    assert not changed.from_cache and changed.key != key  # settings change

    d = yaml.safe_load(sphere_annotation.read_text())
    d["gcs"][0]["keys"][0]["radii"] = [0.95, 0.95]
    sphere_annotation.write_text(yaml.safe_dump(d))
    edited = prepare_shape(sphere_annotation, SMALL, cache)
    assert not edited.from_cache and edited.key not in (key, changed.key)  # annotation change

    trimesh.creation.icosphere(subdivisions=3, radius=1.0).export(sphere_file)
    remeshed = prepare_shape(sphere_annotation, SMALL, cache)
    assert not remeshed.from_cache and remeshed.mesh_faces.shape == (1280, 3)  # mesh change
    assert prepare_shape(sphere_annotation, SMALL, cache).from_cache
    assert load_prepared(remeshed.path).key == remeshed.key


def test_corrupt_cache_is_replaced(sphere_annotation, cache):
    cache.mkdir()
    cache_path(cache, "sphere").write_bytes(b"not an npz")
    with pytest.raises(DataError, match="unreadable"):
        load_prepared(cache_path(cache, "sphere"))
    shape = prepare_shape(sphere_annotation, SMALL, cache)
    assert not shape.from_cache and load_prepared(shape.path).key == shape.key


NAN_PLY = PLY_TRIANGLE_HEADER + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"


def _bad_case(case, tmp_path, gc_dict):
    """(annotation yaml text, words expected in the error) for each kind of bad input."""
    gc = gc_dict("body", -0.3, 0.3)
    doc = {"name": "bad", "mesh": "sphere.ply", "gcs": [gc]}
    if case == "missing_mesh":
        doc["mesh"] = "nowhere.ply"
        return doc, ["nowhere.ply", "not found"]
    if case == "empty_mesh":
        (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
        doc["mesh"] = "points.obj"
        return doc, ["points.obj", "no triangles"]
    if case == "nan_vertices":
        (tmp_path / "nan.ply").write_text(NAN_PLY)
        doc["mesh"] = "nan.ply"
        return doc, ["nan.ply", "NaN"]
    if case == "malformed_yaml":
        return "name: bad\ngcs: [ {name: a\n", ["malformed YAML"]
    if case == "zero_length":
        gc["curve"]["points"] = [[0.1, 0, 0], [0.1, 0, 0]]
        return doc, ["GC 'body'", "zero length"]
    if case == "zero_radius":
        gc["keys"][0]["radii"] = [0.9, 0.0]
        return doc, ["GC 'body'", "radii"]
    if case == "bezier_one_point":
        gc["curve"]["points"] = [[0.1, 0, 0]]
        return doc, ["GC 'body'", "at least 2 points"]
    if case == "not_covering":
        gc["caps"] = [0.01, 0.01]  # flat ends: the sphere's poles along x stick out
        doc["gcs"].append(gc_dict("far", 0.0, 0.2, (0.05, 0.05), (0.05, 0.05)))
        doc["gcs"][1]["curve"]["points"] = [[0.0, -0.9, 0.9], [0.2, -0.9, 0.9]]
        return doc, ["GC 'body'", "cover only", "surface samples are outside", "enlarge the radii or caps"]
    raise KeyError(case)


@pytest.mark.parametrize("case", ["missing_mesh", "empty_mesh", "nan_vertices", "malformed_yaml", "zero_length",
                                  "zero_radius", "bezier_one_point", "not_covering"])
def test_bad_input_raises_and_writes_no_cache(case, tmp_path, sphere_file, write_yaml, gc_dict, cache):
    content, words = _bad_case(case, tmp_path, gc_dict)
    path = write_yaml(content, name=f"{case}.yaml")
    with pytest.raises(DataError) as e:
        prepare_shape(path, SMALL, cache)
    message = str(e.value)
    for w in words:
        assert w in message, message
    assert "Fix:" in message
    if case in ("missing_mesh", "empty_mesh", "nan_vertices"):
        assert f"{case}.yaml" in message  # the annotation whose mesh is bad
    assert not cache.exists() or not any(cache.iterdir())


def test_coverage_error_names_annotation_and_nearest_gc(sphere_file, write_yaml, gc_dict, cache):
    left = gc_dict("left", -0.3, 0.0, (0.9, 0.9), (0.8, 0.05))  # covers x < 0
    right = gc_dict("right", 0.0, 0.3, (0.7, 0.7), (0.6, 0.6))  # too thin for the sphere's x > 0 half
    path = write_yaml({"name": "halves", "mesh": sphere_file.name, "gcs": [left, right]})
    with pytest.raises(DataError) as e:
        prepare_shape(path, SMALL, cache)
    assert e.value.path == str(path) and e.value.gc == "right"
    assert "of 5000 surface samples are outside every GC" in str(e.value)
    assert not cache.exists()
    # the same annotation passes when the threshold allows it, and reports its coverage
    shape = prepare_shape(path, dataclasses.replace(SMALL, min_coverage=0.0), cache)
    assert 0.5 < shape.coverage < 0.9


def test_auto_annotation_of_real_meshes_prepares(tmp_path):
    for spec in ["pyvista:ant.ply", "pyvista:airplane.ply"]:
        shape = prepare_shape(auto_annotation(spec, settings=AutoGCSettings.from_yaml(method="axis")), SMALL, tmp_path)
        assert shape.coverage == 1.0
        inside = shape.sdf < 0
        n_vol = len(shape.points) - shape.n_surface
        uniform = slice(shape.n_surface, len(shape.points) - round(n_vol * SMALL.shell_fraction))
        assert 0.005 < inside[uniform].mean() < 0.9  # thin parts: some uniform samples inside
        #                                              (about 1% of the 750 uniform ones here)


def test_invalid_settings():
    with pytest.raises(DataError, match="surface_fraction"):
        PrepareSettings.from_yaml(surface_fraction=1.5)


@pytest.mark.parametrize("fraction", [0.0, 1.0])
def test_only_surface_or_only_volume_samples(sphere_annotation, fraction):
    shape = prepare_shape(sphere_annotation, dataclasses.replace(SMALL, n_samples=1_000, surface_fraction=fraction))
    assert len(shape.points) == 1_000 and shape.n_surface == int(1_000 * fraction)
    assert shape.pair_point.max() < 1_000


def test_shapes_prepared_in_worker_processes_equal_those_prepared_here(sphere_file, write_yaml,
                                                                        gc_dict, tmp_path):
    """prepare_uncached fills the cache from spawned workers; the samples must be the ones this
    process makes, a cached shape is not made again, and a failing shape is left to the caller."""
    from ngc_gen.data.prepare import prepare_uncached

    anns = [load_annotation(write_yaml({"name": f"s{i}", "mesh": sphere_file.name,
                                        "gcs": [gc_dict("body", -0.3 - 0.1 * i, 0.3)]},
                                       name=f"s{i}.yaml")) for i in range(4)]
    bad = load_annotation(write_yaml({"name": "bad", "mesh": sphere_file.name,
                                      "gcs": [gc_dict("body", -0.1, 0.1, radii=(0.1, 0.1))]},
                                     name="bad.yaml"))
    made = prepare_uncached(anns + [bad], SMALL, tmp_path / "par", workers=2)
    assert sorted(made) == ["s0", "s1", "s2", "s3"] and all(s > 0 for s in made.values())
    for ann in anns:
        here = prepare_shape(ann, SMALL, tmp_path / "seq")
        there = prepare_shape(ann, SMALL, tmp_path / "par")
        assert there.from_cache and not here.from_cache
        for f in ("points", "sdf", "pair_point", "pair_gc", "pair_rel"):
            np.testing.assert_array_equal(getattr(here, f), getattr(there, f))
    assert prepare_uncached(anns, SMALL, tmp_path / "par", workers=2) == {}
    with pytest.raises(DataError, match="cover"):
        prepare_shape(bad, SMALL, tmp_path / "par")


def test_pair_margin_trains_a_gc_past_its_boundary(sphere_file, write_yaml, gc_dict, cache):
    """With pair_margin m a sample pairs with every GC within relative radius 1 + m (the band
    the union hands over in), with its true relative coordinates; the samples stay the same."""
    path = write_yaml({"name": "two", "mesh": sphere_file.name,
                       "gcs": [gc_dict("left", -0.6, 0.1), gc_dict("right", -0.1, 0.6)]})
    plain = prepare_shape(path, SMALL, cache)
    wide = prepare_shape(path, dataclasses.replace(SMALL, pair_margin=0.2), cache)
    np.testing.assert_array_equal(wide.points, plain.points)
    np.testing.assert_array_equal(wide.sdf, plain.sdf)
    assert wide.key != plain.key
    rho = np.sqrt(GeneralizedCylinder.relative_measure(wide.pair_rel.astype(np.float64)))
    assert rho.max() <= 1.2 + 1e-6
    band = rho > 1.0
    assert band.sum() > 200                   # new pairs, all in the band past a boundary
    assert len(wide.pair_point) == len(plain.pair_point) + band.sum()
    gcs = wide.gcs()
    for g, gc in enumerate(gcs):
        sel = wide.pair_gc == g
        np.testing.assert_allclose(gc.to_world(wide.pair_rel[sel].astype(np.float64)),
                                   wide.points[wide.pair_point[sel]], atol=1e-4)
        # every sample within the margin of the GC is paired with it, none further out
        rel = np.asarray(gc.to_relative(wide.points.astype(np.float64)))
        near = np.sqrt(GeneralizedCylinder.relative_measure(rel)) <= 1.2
        np.testing.assert_array_equal(np.sort(wide.pair_point[sel]), np.flatnonzero(near))
    with pytest.raises(DataError, match="pair_margin"):
        PrepareSettings.from_yaml(pair_margin=-0.1)


def test_shell_samples_lie_where_a_gc_fades_out(sphere_file, write_yaml, gc_dict, cache):
    """With shell_fraction f, f of the volume samples lie in their GCs' outer shells (relative
    radius in [1 - shell_width, 1] in a GC that holds them), paired like any volume sample;
    the rest stay uniform in the union; at f = 0 the width is no part of the cache key."""
    path = write_yaml({"name": "two", "mesh": sphere_file.name,
                       "gcs": [gc_dict("left", -0.6, 0.1), gc_dict("right", -0.1, 0.6)]})
    none = dataclasses.replace(SMALL, shell_fraction=0.0)
    plain = prepare_shape(path, none, cache)
    assert plain.key == prepare_shape(path, dataclasses.replace(none, shell_width=0.5),
                                      cache).key
    shelled = prepare_shape(path, dataclasses.replace(SMALL, shell_fraction=0.5,
                                                      shell_width=0.1), cache)
    assert shelled.key != plain.key
    gcs = shelled.gcs()
    rho = np.stack([np.sqrt(GeneralizedCylinder.relative_measure(np.asarray(
        g.to_relative(shelled.points[shelled.n_surface:].astype(np.float64))))) for g in gcs])
    in_shell = ((rho >= 0.9 - 1e-5) & (rho <= 1.0 + 1e-5)).any(0)
    n_vol = len(shelled.points) - shelled.n_surface
    assert in_shell[n_vol - n_vol // 2:].all()          # the shell half: every one in a shell
    uniform = in_shell[:n_vol - n_vol // 2].mean()      # the rest: about the shells' volume
    assert 0.1 < uniform < 0.45 and in_shell.mean() > uniform + 0.25
    for g, gc in enumerate(gcs):                         # paired with every GC holding it
        sel = shelled.pair_gc == g
        np.testing.assert_allclose(gc.to_world(shelled.pair_rel[sel].astype(np.float64)),
                                   shelled.points[shelled.pair_point[sel]], atol=1e-4)
        held = np.flatnonzero(rho[g] <= 1.0 + 1e-6) + shelled.n_surface
        vol_pairs = np.sort(shelled.pair_point[sel][shelled.pair_point[sel] >= shelled.n_surface])
        np.testing.assert_array_equal(vol_pairs, held)
    with pytest.raises(DataError, match="shell_width"):
        PrepareSettings.from_yaml(shell_width=0.0)


def test_overlap_samples_lie_where_gcs_overlap(sphere_file, write_yaml, gc_dict, cache):
    """With overlap_fraction f, f of the volume samples lie in two or more GCs (taken from the
    uniform share; the shells keep theirs), paired with every GC holding them."""
    path = write_yaml({"name": "two", "mesh": sphere_file.name,
                       "gcs": [gc_dict("left", -0.6, 0.1), gc_dict("right", -0.1, 0.6)]})
    plain = prepare_shape(path, SMALL, cache)
    mixed = prepare_shape(path, dataclasses.replace(SMALL, overlap_fraction=0.25), cache)
    assert mixed.key != plain.key
    n_vol = len(mixed.points) - mixed.n_surface
    n_overlap = round(0.25 * n_vol)
    held = np.bincount(mixed.pair_point, minlength=len(mixed.points))
    assert (held[len(mixed.points) - n_overlap:] >= 2).all()     # the overlap share: in both
    before = np.bincount(plain.pair_point, minlength=len(plain.points))[plain.n_surface:]
    assert (held[mixed.n_surface:] >= 2).mean() > (before >= 2).mean() + 0.1
    with pytest.raises(DataError, match="overlap_fraction"):
        dataclasses.replace(SMALL, overlap_fraction=0.6)          # 0.5 + 0.6 > 1
