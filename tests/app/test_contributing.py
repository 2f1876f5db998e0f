"""docs/contributing.md's "Add a stage" works as written: its module and its registry entry,
taken from the page's own code blocks, make a stage that train.py's registry runs (checks
included) and that writes its run file."""
from __future__ import annotations

import json
import re
import sys
import types

import pytest

from ngc_gen import workspace
from ngc_gen.app.runtime.errors import ConfigError
from ngc_gen.app.stages import registry

from ..helpers import ROOT, compose_config

MODULE = "ngc_gen.app.stages.count_gcs"


def stage_example() -> tuple[str, str]:
    """(the module's source, the registry entry) from the "Add a stage" section."""
    text = (ROOT / "docs" / "contributing.md").read_text()
    section = text.split("## Add a stage", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    module = next(b for b in blocks if "def run_count_gcs" in b)
    entry = next(b for b in blocks if b.lstrip().startswith('"count_gcs"'))
    return module, entry.strip().rstrip(",")


@pytest.fixture
def toy_stage(monkeypatch):
    source, entry = stage_example()
    module = types.ModuleType(MODULE)
    module.__package__ = "ngc_gen.app.stages"
    monkeypatch.setitem(sys.modules, MODULE, module)
    exec(compile(source, "docs/contributing.md", "exec"), module.__dict__)
    name, stage = eval("(" + entry.replace(":", ",", 1) + ")", vars(registry))
    monkeypatch.setitem(registry.STAGES, name, stage)
    return name


def test_the_documented_stage_runs(toy_stage, tmp_path):
    cfg = compose_config(overrides=[f"stage={toy_stage}", "data=ant", f"run_dir={tmp_path}"])
    counts = registry.run_stage(cfg)
    assert counts == {"ant": 15}  # the ant annotation's GCs (datasets/ant/ant.yaml)
    assert json.loads(workspace.metrics(tmp_path).read_text()) == counts


def test_the_documented_stage_is_checked_first(toy_stage, tmp_path):
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "bad.off").write_text("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n")
    cfg = compose_config(overrides=[f"stage={toy_stage}", "data=folder",
                                    f"data.path={tmp_path / 'meshes'}",
                                    f"run_dir={tmp_path / 'run'}"])
    with pytest.raises(ValueError, match=r"bad\.off.*no triangles"):
        registry.run_stage(cfg)
    assert not (tmp_path / "run").exists()


def test_an_unknown_stage_names_the_documented_one(toy_stage):
    with pytest.raises(ConfigError, match="count_gcs"):
        registry.check_inputs(compose_config(overrides=["stage=count"]))
