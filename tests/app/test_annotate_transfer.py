"""`train.py stage=annotate annotate.template=T` on a folder: every matching mesh gets T's GCs
(files, the folder picture and table), a chair in the folder is one refused row, and
annotate.export_template writes a template the next run accepts."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ngc_gen.app.stages.registry import run_stage
from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.autogc.template import load_template

from ..data.autogc.shapes import chair, quadruped
from ..helpers import ROOT, compose_config

pytestmark = pytest.mark.usefixtures("single_thread")
TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
SMALL = ["annotate.resolution=64", "annotate.samples=5000"]


def test_a_folder_gets_one_layout_and_the_chair_is_refused(tmp_path, capsys):
    d = tmp_path / "meshes"
    d.mkdir()
    quadruped()[0].export(d / "cow.ply")
    quadruped(1.0, 0.6, 0.35, 0.5)[0].export(d / "dachshund.ply")
    chair().export(d / "chair.ply")
    run = tmp_path / "run"
    out = tmp_path / "exported.yaml"
    cfg = compose_config(overrides=["stage=annotate", "data=folder", f"data.path={d}",
                                    f"run_dir={run}", f"annotate.template={TEMPLATE}",
                                    f"annotate.export_template={out}", *SMALL])
    rows = run_stage(cfg)
    by = {r["mesh"]: r for r in rows}
    assert "does not match template quadruped" in by["chair"]["error"]
    names = load_template(TEMPLATE).names
    for mesh in ("cow", "dachshund"):
        ann = load_annotation(run / f"{mesh}.yaml")
        assert ann.gc_names == names and by[mesh]["missing"] == []
        assert (run / f"{mesh}_gcs.png").is_file()
    assert not (run / "chair.yaml").exists()
    table = json.loads((run / "transfer.json").read_text())
    assert [r["mesh"] for r in table["meshes"]] == [r["mesh"] for r in rows]
    assert (run / "transfer.png").is_file()
    printed = capsys.readouterr().out
    assert "refused" in printed and "cow" in printed
    exported = load_template(out)
    assert exported.names == names and exported.placed
    # an annotated mesh's YAML is a template too
    cfg = compose_config(overrides=["stage=annotate", "data=folder", f"data.path={d}",
                                    f"run_dir={tmp_path / 'run2'}",
                                    f"annotate.template={run / 'cow.yaml'}", *SMALL])
    rows2 = {r["mesh"]: r for r in run_stage(cfg)}
    assert load_annotation(tmp_path / "run2" / "dachshund.yaml").gc_names == names
    assert "error" in rows2["chair"]
    assert np.isfinite(rows2["dachshund"]["cost"])
