"""Fifteen malformed mesh files (`malformed_meshes.py`) given to `train.py data=folder`: each is
refused before torch or trimesh loads (that is what keeps a refusal within 2 s; bench/cli.py
times it: malformed_mesh_slowest_s), with exit code 2, one line naming the file and what is
wrong, and nothing written."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from ..helpers import ROOT, run_entry
from .malformed_meshes import write_malformed

# every file through train.py's own check, in one fresh process: which modules it loaded
CHECK_ALL = """
import json, sys
from ngc_gen.app.runtime.config import compose_config, register_resolvers
from ngc_gen.app.stages.registry import check_inputs
from ngc_gen.data.errors import DataError
register_resolvers()
out = {}
for case, folder in json.loads(sys.argv[1]).items():
    cfg = compose_config("train", ["stage=fit", "data=folder", f"data.path={folder}"])
    try:
        check_inputs(cfg)
        out[case] = None
    except DataError as e:
        out[case] = str(e)
out["_heavy"] = sorted(m for m in ("torch", "trimesh", "lightning") if m in sys.modules)
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def malformed(tmp_path_factory):
    return write_malformed(tmp_path_factory.mktemp("malformed"))


def test_every_malformed_file_is_refused_before_torch_loads(malformed):
    folders = {case: str(path.parent) for case, (path, _) in malformed.items()}
    r = subprocess.run([sys.executable, "-c", CHECK_ALL, json.dumps(folders)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out.pop("_heavy") == []
    assert len(out) == 15
    for case, (path, words) in malformed.items():
        message = out[case]
        assert message is not None, f"{case}: accepted"
        assert message.startswith(str(path)) and re.search(words, message), (case, message)
        assert "\n" not in message and "Fix: " in message, message


@pytest.mark.parametrize("case", ["gltf_recursive_nodes", "glb_truncated", "off_no_faces"])
def test_the_command_exits_2_with_one_line_and_writes_nothing(case, malformed, tmp_path):
    path, words = malformed[case]
    run = tmp_path / "run"
    before = sorted(path.parent.iterdir())
    r = run_entry("train.py", "stage=fit", "data=folder", f"data.path={path.parent}",
                  f"hydra.run.dir={run}", cwd=tmp_path, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.rstrip("\n").split("\n")
    assert len(lines) == 1 and lines[0].startswith("error: ") and re.search(words, lines[0])
    assert not run.exists() and sorted(path.parent.iterdir()) == before
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    "gltf_broken_json", "gltf_missing_bin", "gltf_index_out_of_range", "gltf_infinite_vertices",
    "gltf_accessor_missing", "gltf_short_bin", "glb_broken_json", "off_index_out_of_range",
    "ply_truncated", "ply_infinite_vertices", "obj_index_out_of_range", "stl_truncated"])
def test_the_command_refuses_the_other_kinds_too(case, malformed, tmp_path):
    test_the_command_exits_2_with_one_line_and_writes_nothing(case, malformed, tmp_path)


def test_the_full_reader_refuses_them_too(malformed):
    """The light check and `load_mesh` agree: what the check refuses, trimesh-based loading
    refuses as well (so the check adds speed, not a second opinion)."""
    from ngc_gen.data.errors import DataError
    from ngc_gen.data.mesh.io import load_mesh

    accepted = []
    for case, (path, _) in malformed.items():
        try:
            load_mesh(path)
            accepted.append(case)
        except (DataError, RecursionError):
            pass
    assert accepted == []
