"""`python train.py stage=prepare` on the real configs: caches, coverage, and clean failures.
(Every data config builds with its YAML's values: tests/app/test_config.py.)"""
import trimesh
import yaml

from ..helpers import run_entry


def test_folder_dataset_prepares_with_auto_gc(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    trimesh.creation.capsule(height=1.0, radius=0.3).export(meshes / "pill.obj")
    trimesh.creation.box(extents=[1.0, 0.5, 0.3]).export(meshes / "brick.stl")
    out = tmp_path / "out"
    r = run_entry("train.py", "stage=prepare", "data=folder", f"data.path={meshes}",
                  f"paths.cache_dir={tmp_path / 'cache'}", "prepare.n_samples=5000",
                  f"hydra.run.dir={out}")
    assert r.returncode == 0, r.stderr
    assert "pill" in r.stdout and "brick" in r.stdout and "100.000%" in r.stdout
    assert "pill: GCs trunk" in r.stdout  # every shape's GC names are printed
    cached = sorted(p.name for p in (tmp_path / "cache/prepared/meshes").glob("*.npz"))
    assert cached == ["brick.npz", "pill.npz"]


def test_uncovered_mesh_fails_cleanly(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    trimesh.creation.box(extents=[1.0, 1.0, 1.0]).export(meshes / "cube.ply")
    (meshes / "cube.yaml").write_text(yaml.safe_dump({
        "name": "cube", "mesh": "cube.ply", "normalize": {"bound": 0.8},
        "gcs": [{"name": "core", "curve": {"type": "bezier", "points": [[0, 0, -0.1], [0, 0, 0.1]]},
                 "keys": [{"t": 0, "radii": [0.2, 0.2]}], "caps": [0.1, 0.1]}]}))
    r = run_entry("train.py", "stage=prepare", "data=folder", f"data.path={meshes}",
                  f"paths.cache_dir={tmp_path / 'cache'}", "prepare.n_samples=5000",
                  f"hydra.run.dir={tmp_path / 'out'}")
    assert r.returncode == 2
    assert "error:" in r.stderr and "cube.yaml" in r.stderr and "Traceback" not in r.stderr
    assert not list((tmp_path / "cache").rglob("*.npz"))


def test_missing_folder_fails_cleanly(tmp_path):
    r = run_entry("train.py", "stage=prepare", "data=folder", f"data.path={tmp_path / 'nope'}",
                  f"paths.cache_dir={tmp_path / 'cache'}", f"hydra.run.dir={tmp_path / 'out'}")
    assert r.returncode == 2 and "does not exist" in r.stderr
