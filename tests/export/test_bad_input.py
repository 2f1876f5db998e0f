"""Bad export input: one line `error: ...`, exit code 2, no file written, found by the checks
that run before the runner (and before torch loads; bench/export.py times the real command)."""
from __future__ import annotations

import pytest
import torch

from ngc_gen.app.runtime.cli import run_job
from ngc_gen.app.stages.export_shape import check_export

from ..helpers import run_entry
from .conftest import export_config


@pytest.fixture(scope="module")
def empty_run(tmp_path_factory):
    """A fitting checkpoint that holds no shapes."""
    path = tmp_path_factory.mktemp("empty") / "last.ckpt"
    torch.save({"hyper_parameters": {"checkpoint_kind": "ngc_gen.autodecoder", "kind": "ngc",
                                     "meta": {"shapes": []}}, "state_dict": {}}, path)
    return path


CASES = {  # name: (run fixture, overrides, words the error names)
    "unknown_clip": ("fit_ckpt", ["clip=edit:no_such_program"], "unknown edit program"),
    "unknown_clip_kind": ("fit_ckpt", ["clip=walk"], "unknown clip kind"),
    "unknown_rig_clip": ("animal_ckpt", ["clip=rig:MINI/Moonwalk"], "unknown clip"),
    "clip_lacks_names": ("auto_ckpt", ["clip=rig:horse/Walk"], "none in common"),
    "no_shapes": ("empty_run", [], "holds no shapes"),
    "zero_joints": ("fit_ckpt", ["export.joints_per_gc=0"], "joints_per_gc"),
    "missing_folder": ("fit_ckpt", ["out=MISSING"], "folder does not exist"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_export(case, request, tmp_path, capsys):
    fixture, overrides, words = CASES[case]
    run = request.getfixturevalue(fixture)
    out = tmp_path / "shape.glb"
    overrides = [o.replace("MISSING", str(tmp_path / "no" / "shape.glb")) for o in overrides]
    if any("MINI" in o for o in overrides):  # a rig file without that clip
        from .test_export import _mini_rig

        rig = tmp_path.parent / f"{case}_rig.glb"
        _mini_rig(rig, 10.0)
        overrides = [o.replace("MINI", str(rig)) for o in overrides]
    cfg = export_config(run, out, *overrides)

    def never(cfg):
        raise AssertionError("the export ran past its checks")

    with pytest.raises(SystemExit) as e:
        run_job(never, cfg, check=check_export)
    assert e.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and words in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_cli_one_line(auto_ckpt, tmp_path):
    """The command itself: exit 2, one line, no file."""
    r = run_entry("sample.py", "mode=export", f"run={auto_ckpt}", "clip=rig:horse/Walk",
                  f"hydra.run.dir={tmp_path}/h", "threads=1")
    assert r.returncode == 2, r.stderr
    lines = [x for x in r.stderr.strip().splitlines() if x.startswith("error:")]
    assert len(lines) == 1 and "none in common" in lines[0]
    assert not list(tmp_path.glob("**/*.glb"))
