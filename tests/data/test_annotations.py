"""Annotation YAML: round trip, path resolution, and one clear DataError per kind of mistake."""

from __future__ import annotations

import os

import pytest
import yaml

from ngc_gen.data.annotations import annotation_from_dict, load_annotation, save_annotation
from ngc_gen.data.errors import DataError


def test_round_trip(tmp_path, sphere_annotation):
    ann = load_annotation(sphere_annotation)
    assert ann.name == "sphere" and ann.bound == 0.8 and ann.gc_names == ["body"]
    assert ann.mesh_path == tmp_path / "sphere.ply"
    out = save_annotation(ann, tmp_path / "sub" / "copy.yaml")
    # outside the new file's folder: absolute, so the YAML can move without losing its mesh
    assert yaml.safe_load(out.read_text())["mesh"] == str(tmp_path / "sphere.ply")
    beside = save_annotation(ann, tmp_path / "beside.yaml")  # inside: relative, moves with it
    assert yaml.safe_load(beside.read_text())["mesh"] == "sphere.ply"
    again = load_annotation(out)
    assert again.to_dict() == ann.to_dict()
    assert again.mesh_path == ann.mesh_path


def test_defaults_and_relative_mesh_path(tmp_path, write_yaml, gc_dict, monkeypatch):
    path = write_yaml({"mesh": "meshes/m.obj", "gcs": [gc_dict("a", 0, 1)]}, name="chair.yaml")
    monkeypatch.chdir("/")
    ann = load_annotation(path)
    assert ann.name == "chair" and ann.bound == 0.8
    assert ann.mesh_path == tmp_path / "meshes" / "m.obj"  # relative to the YAML, not the cwd


def test_normalize_false_keeps_the_mesh_frame(tmp_path, sphere_annotation, gc_dict):
    """`normalize: false` (edit.py's edited.yaml): round trip, and preparation uses the mesh's
    own coordinates, not the [-bound, bound]^3 fit."""
    from ngc_gen.data.prepare import PrepareSettings, prepare_shape

    d = {**yaml.safe_load(sphere_annotation.read_text()), "normalize": False,
         "gcs": [gc_dict("body", -0.4, 0.4, radii=(1.1, 1.1), caps=(0.8, 0.8))]}
    path = tmp_path / "as_is.yaml"
    path.write_text(yaml.safe_dump(d))
    ann = load_annotation(path)
    assert ann.bound is None and ann.to_dict()["normalize"] is False
    assert load_annotation(save_annotation(ann, tmp_path / "copy.yaml")).bound is None
    prepared = prepare_shape(ann, PrepareSettings.from_yaml(n_samples=1000, coverage_samples=2000))
    r = (prepared.mesh_vertices ** 2).sum(1) ** 0.5
    assert abs(r.max() - 1.0) < 1e-6  # the unit sphere as it is (normalised: radius 0.8)


def test_resource_mesh_is_kept(tmp_path, gc_dict):
    ann = annotation_from_dict({"name": "ant", "mesh": "pyvista:ant.ply", "gcs": [gc_dict("a", 0, 1)]})
    assert ann.mesh == "pyvista:ant.ply" and ann.mesh_path.name == "ant.ply"
    out = save_annotation(ann, tmp_path / "ant.yaml")
    assert yaml.safe_load(out.read_text())["mesh"] == "pyvista:ant.ply"


def test_save_is_atomic(tmp_path, sphere_annotation, monkeypatch):
    ann = load_annotation(sphere_annotation)
    target = tmp_path / "keep.yaml"
    target.write_text("old")
    monkeypatch.setattr(type(ann), "to_yaml", lambda self, relative_to=None: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        save_annotation(ann, target)
    assert target.read_text() == "old"
    assert sorted(os.listdir(tmp_path)) == ["keep.yaml", "shape.yaml", "sphere.ply"]  # no temp left


def _gc(**changes):
    d = {"name": "leg", "curve": {"type": "bezier", "points": [[0, 0, 0], [1, 0, 0]]}, "up": [0, 0, 1],
         "keys": [{"t": 0.0, "radii": [0.1, 0.1], "twist": 0.0}], "caps": [0.1, 0.1]}
    for k, v in changes.items():
        if v is None:
            d.pop(k)
        else:
            d[k] = v
    return d


def _doc(gcs=None, **top):
    d = {"name": "s", "mesh": "m.ply", "gcs": [_gc()] if gcs is None else gcs}
    d.update(top)
    return d


BAD = {
    "malformed_yaml": ("name: s\ngcs: [\n  {name: a\n", None, ["malformed YAML", "line"]),
    "duplicate_yaml_key": ("name: s\nname: t\nmesh: m.ply\n", None, ["appears twice"]),
    "not_a_mapping": ("- 1\n- 2\n", None, ["mapping"]),
    "unknown_top_key": (_doc(mesh_file="x"), None, ["unknown keys", "mesh_file"]),
    "missing_mesh": ({"name": "s", "gcs": [_gc()]}, None, ["'mesh'"]),
    "no_gcs": (_doc(gcs=[]), None, ["'gcs'", "non-empty"]),
    "bad_bound": (_doc(normalize={"bound": -1}), None, ["normalize.bound"]),
    "normalize_true": (_doc(normalize=True), None, ["normalize", "false"]),
    "gc_without_name": (_doc(gcs=[_gc(name=None)]), None, ["gcs[0].name"]),
    "duplicate_gc_names": (_doc(gcs=[_gc(), _gc()]), "leg", ["more than once"]),
    "unknown_gc_field": (_doc(gcs=[_gc(radius=1)]), "leg", ["unknown", "radius"]),
    "missing_keys": (_doc(gcs=[_gc(keys=None)]), "leg", ["'keys'"]),
    "radius_not_a_number": (_doc(gcs=[_gc(keys=[{"t": 0, "radii": ["a", 0.1]}])]), "leg",
                            ["keys[0].radii[0]"]),
    "caps_bool": (_doc(gcs=[_gc(caps=[True, 0.1])]), "leg", ["caps[0]"]),
    "zero_length": (_doc(gcs=[_gc(curve={"type": "bezier", "points": [[0, 0, 0], [0, 0, 0]]})]), "leg",
                    ["curve.points", "zero length"]),
    "zero_radius": (_doc(gcs=[_gc(keys=[{"t": 0, "radii": [0.0, 0.1]}])]), "leg", ["keys[0].radii", "positive"]),
    "bezier_one_point": (_doc(gcs=[_gc(curve={"type": "bezier", "points": [[0, 0, 0]]})]), "leg",
                         ["curve.points", "at least 2"]),
    "unknown_curve_type": (_doc(gcs=[_gc(curve={"type": "nurbs", "points": [[0, 0, 0], [1, 0, 0]]})]), "leg",
                           ["curve.type"]),
    "up_parallel": (_doc(gcs=[_gc(up=[1, 0, 0])]), "leg", ["'up'"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_annotation_names_file_gc_field_and_fix(write_yaml, case):
    content, gc_name, words = BAD[case]
    path = write_yaml(content, name=f"{case}.yaml")
    with pytest.raises(DataError) as e:
        load_annotation(path)
    message = str(e.value)
    assert f"{case}.yaml" in message and "Fix:" in message, message
    if gc_name is not None:
        assert f"GC '{gc_name}'" in message and e.value.gc == gc_name, message
    for w in words:
        assert w in message, message


def test_missing_annotation_file(tmp_path):
    with pytest.raises(DataError, match="not found"):
        load_annotation(tmp_path / "none.yaml")
