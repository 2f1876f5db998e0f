"""`train.py stage=annotate`: files in the run directory and beside the meshes, the printed
table, hand annotations left alone, and `data=folder` without YAML using skeleton GCs."""
from __future__ import annotations

import shutil

import hydra
import pytest
import trimesh
import yaml

from ngc_gen.data.annotations import load_annotation
from ngc_gen.app.stages.registry import run_stage
from ngc_gen.app.stages.annotate import HEADER

from ..helpers import compose_config
from ..data.autogc.test_skeleton_gcs import tube_union

pytestmark = pytest.mark.usefixtures("single_thread")
SMALL = ["annotate.resolution=48", "annotate.samples=3000"]


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "meshes"
    d.mkdir()
    tube_union([((0, 0, 0), (0.8, 0, 0)), ((0, 0, 0), (-0.4, 0.6, 0)),
                ((0, 0, 0), (-0.4, -0.6, 0))]).export(d / "tripod.ply")
    trimesh.creation.box(extents=[1.0, 0.5, 0.4]).export(d / "box.ply")
    hand = {"name": "box", "mesh": "box.ply", "gcs": [{
        "name": "body", "curve": {"type": "bezier", "points": [[-0.5, 0, 0], [0.5, 0, 0]]},
        "up": [0, 0, 1], "keys": [{"t": 0.0, "radii": [0.6, 0.6]}], "caps": [0.4, 0.4]}]}
    (d / "box.yaml").write_text(yaml.safe_dump(hand))
    return d


def annotate(folder, run_dir, *extra):
    cfg = compose_config(overrides=["stage=annotate", "data=folder", f"data.path={folder}",
                                    f"run_dir={run_dir}", *SMALL, *extra])
    return run_stage(cfg)


def test_writes_annotations_pictures_and_a_table(folder, tmp_path, capsys):
    run = tmp_path / "run"
    rows = annotate(folder, run, "annotate.write_beside=true")
    out = capsys.readouterr().out
    assert [r["mesh"] for r in rows] == ["box", "tripod"]
    for name in ("box", "tripod"):
        ann = load_annotation(run / f"{name}.yaml")  # loadable, mesh path resolves
        assert ann.mesh_path.samefile(folder / f"{name}.ply")
        png = (run / f"{name}_gcs.png").read_bytes()
        assert int.from_bytes(png[16:20], "big") >= 1200  # two 640 px cells
        assert int.from_bytes(png[20:24], "big") >= 500
    tripod = load_annotation(run / "tripod.yaml")
    assert len(tripod.gcs) == 3 and tripod.gc_names[0] == "trunk"
    # the run moves (renamed, copied elsewhere): its YAMLs still find their meshes
    moved = tmp_path / "elsewhere" / "deeper" / "run"
    shutil.copytree(run, moved)
    for name in ("box", "tripod"):
        assert load_annotation(moved / f"{name}.yaml").mesh_path.samefile(folder / f"{name}.ply")
    assert yaml.safe_load((folder / "tripod.yaml").read_text())["mesh"] == "tripod.ply"
    assert all(r["coverage"] >= 0.999 for r in rows)
    assert "coverage" in out and "seconds" in out and "tripod: GCs trunk" in out
    # beside the meshes: the tripod's is written, the hand annotation of the box is kept
    assert (folder / "tripod.yaml").read_text().startswith(HEADER)
    assert (folder / "tripod_gcs.png").is_file()
    assert load_annotation(folder / "box.yaml").gc_names == ["body"]
    assert "kept the hand annotation" in out
    # a second run may overwrite what the stage wrote itself
    (folder / "tripod.yaml").write_text(HEADER + "stale: true\n")
    annotate(folder, tmp_path / "run2", "annotate.write_beside=true", "annotate.method=axis")
    assert load_annotation(folder / "tripod.yaml").gc_names == ["body"]


def test_nothing_beside_the_meshes_by_default(folder, tmp_path):
    annotate(folder, tmp_path / "run", "annotate.method=axis")
    assert sorted(p.name for p in folder.iterdir()) == ["box.ply", "box.yaml", "tripod.ply"]
    assert load_annotation(tmp_path / "run" / "tripod.yaml").gc_names == ["body"]


def test_folder_without_yaml_uses_skeleton_gcs(folder, tmp_path):
    cfg = compose_config(overrides=["data=folder", f"data.path={folder}", "run_dir=/tmp", *SMALL])
    shapes = {a.name: a for a in hydra.utils.instantiate(cfg.data).shapes()}
    assert shapes["box"].gc_names == ["body"]  # the hand annotation
    assert len(shapes["tripod"].gcs) == 3 and shapes["tripod"].gc_names[0] == "trunk"
