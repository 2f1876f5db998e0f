"""`experiment=collection`: a folder of meshes to a generator in one command. The plan links
the steps (annotate -> shape_latent -> diffusion -> sample, interpolate); bad input is refused
in one line, exit 2, before torch loads where no mesh needs reading."""
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import trimesh
import yaml

from ngc_gen.app.stages.collection import check_annotated, interpolation_pair
from ngc_gen.app.stages.pipeline import planned_steps
from ngc_gen.data.errors import DataError

from ..conftest import straight_gc
from ..helpers import ROOT, compose_config, run_entry

TEMPLATE = "datasets/animals/quadruped_transfer.yaml"


def collection(tmp_path, *extra, n=3):
    meshes = tmp_path / "meshes"
    meshes.mkdir(exist_ok=True)
    for i in range(n):
        trimesh.creation.icosphere(1).export(meshes / f"m{i}.ply")
    return compose_config("train", ["experiment=collection", f"data.path={meshes}",
                                    f"annotate.template={ROOT / TEMPLATE}",
                                    f"run_dir={tmp_path / 'run'}", *extra])


def test_the_plan_links_every_step(tmp_path):
    cfg = collection(tmp_path, "threads=1")
    run = tmp_path / "run"
    steps = {s: (c, o) for s, c, o in planned_steps(cfg, run)}
    assert list(steps) == ["annotate", "shape_latent", "diffusion", "sample", "interpolate"]
    ann = steps["annotate"][0]
    assert ann.stage == "annotate" and ann.data.path == cfg.data.path
    assert ann.annotate.template == str(ROOT / TEMPLATE) and ann.threads == 1
    sl = steps["shape_latent"][0]
    assert sl.data.path == str(run / "annotate") and sl.data.name == "meshes"
    assert sl.prepare.cache_dir == str(run / "prepared")
    diff = steps["diffusion"][0]
    assert diff.shape_latent_run == str(run / "shape_latent")
    assert diff.diffusion.standardise == "pca" and diff.diffusion.augment.min_latents == 1024
    assert steps["sample"][0].run == str(run / "diffusion")
    assert steps["interpolate"][0].mode == "interpolate"


def test_annotated_folders_train_and_mixed_frames_are_refused(tmp_path):
    """data=folder on an annotate run's directory reads its YAMLs; YAMLs of two frames stop
    stage=shape_latent before anything is prepared."""
    from ngc_gen.data.datasets import MeshFolder
    from ngc_gen.app.runtime.checks import check_frames

    mesh = tmp_path / "ball.ply"
    trimesh.creation.icosphere(1).export(mesh)
    run = tmp_path / "annotate"
    run.mkdir()
    (run / "config.yaml").write_text("stage: annotate\n")
    for name, up in (("a", [0, 1, 0]), ("b", [0, 1, 0])):
        (run / f"{name}.yaml").write_text(yaml.safe_dump(
            {"name": name, "mesh": str(mesh), "frame": {"up": up, "front": [0, 0, 1]},
             "gcs": [straight_gc("torso", -0.3, 0.3)]}))
    assert [a.name for a in MeshFolder("x", str(run)).shapes()] == ["a", "b"]
    node = {"_target_": "ngc_gen.data.datasets.MeshFolder", "path": str(run)}
    check_frames(node)
    (run / "b.yaml").write_text(yaml.safe_dump(
        {"name": "b", "mesh": str(mesh), "frame": {"up": [0, 0, 1], "front": [1, 0, 0]},
         "gcs": [straight_gc("torso", -0.3, 0.3)]}))
    with pytest.raises(DataError, match="b is written facing .* but a .* one body frame"):
        check_frames(node)


def test_every_mesh_refused_or_one_left_is_one_line():
    with pytest.raises(DataError, match="every mesh was refused by the template"):
        check_annotated([{"mesh": "chair", "error": "no match"}], "DIR")
    with pytest.raises(DataError, match="only cow matched"):
        check_annotated([{"mesh": "cow"}, {"mesh": "chair", "error": "no match"}], "DIR")
    check_annotated([{"mesh": "cow"}, {"mesh": "camel"}], "DIR")


def test_the_interpolation_runs_between_two_of_the_users_meshes(tmp_path):
    z = torch.tensor([[0.0, 0.0], [1.0, 0.0], [5.0, 1.0], [2.0, 2.0]])
    (tmp_path / "sl").mkdir()
    torch.save({"names": ["cow", "pig", "camel", "bull"], "latents": z},
               tmp_path / "sl" / "latents.pt")
    assert interpolation_pair(tmp_path / "sl") == ("cow", "camel")


CHECK = """
import sys
from ngc_gen.app.runtime.config import compose_config
from ngc_gen.app.stages.registry import check_inputs
from ngc_gen.data.errors import DataError
cfg = compose_config("train", sys.argv[1:])
try:
    check_inputs(cfg)
    print("ok")
except DataError as e:
    print("error:", e)
print("torch loaded" if "torch" in sys.modules else "torch not loaded")
"""


@pytest.mark.parametrize("case,n,extra,match", [
    ("one mesh", 1, [], r"has 1 mesh \(m0.ply\); a generator needs at least 2"),
    ("no template", 3, ["annotate.template=nowhere.yaml"], "template nowhere.yaml does not exist"),
])
def test_bad_collections_are_refused_before_torch(tmp_path, case, n, extra, match):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for i in range(n):
        trimesh.creation.icosphere(1).export(meshes / f"m{i}.ply")
    args = ["experiment=collection", f"data.path={meshes}", f"annotate.template={ROOT / TEMPLATE}",
            *extra]
    r = subprocess.run([sys.executable, "-c", CHECK, *args, f"run_dir={tmp_path / 'run'}"],
                       capture_output=True, text=True,
                       cwd=ROOT, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    lines = r.stdout.strip().splitlines()
    assert lines[-1] == "torch not loaded", r.stdout + r.stderr
    assert re.search(match, lines[0]) and "Fix:" in lines[0], lines
    # the command a user types: one line, exit 2, no run directory
    r = run_entry("train.py", *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.startswith("error: "), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "run").exists()
