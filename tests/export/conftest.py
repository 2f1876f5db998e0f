"""Export fixtures: tube-weight checkpoints (a real NGCDecoder, no fitting, as tests/edit uses):
the edit tests' three GCs (body, arm, tail), the same GCs under the quadruped template's names,
and the automatic GCs of a small tube mesh; a config composer for `sample.py mode=export`."""
from __future__ import annotations

import pytest

from ngc_gen.lit.autodecoder import AutoDecoder

from ..edit.conftest import GC_DICTS, make_module, save_checkpoint
from ..helpers import compose_config

#: the edit tests' GCs renamed after the quadruped template (datasets/animals/quadruped.yaml)
TEMPLATE_NAMES = {"body": "torso", "arm": "leg_fl", "tail": "tail"}
SMALL = ["export.resolution=32", "export.joints_per_gc=3", "export.picture=false"]


def module_of(gc_dicts, shapes=("one",), seed=0) -> AutoDecoder:
    """An AutoDecoder holding `shapes`, each with GCs `gc_dicts`, with tube weights."""
    return make_module(seed, shapes, gc_dicts)


def _saved(tmp_path_factory, module, name):
    path = tmp_path_factory.mktemp(name) / "checkpoints" / "last.ckpt"
    path.parent.mkdir(parents=True)
    save_checkpoint(module, path)
    return path


@pytest.fixture(scope="session")
def fit_ckpt(tmp_path_factory):
    return _saved(tmp_path_factory, module_of(GC_DICTS, ("one", "two")), "fit")


@pytest.fixture(scope="session")
def animal_ckpt(tmp_path_factory):
    gcs = [{**d, "name": TEMPLATE_NAMES[d["name"]]} for d in GC_DICTS]
    return _saved(tmp_path_factory, module_of(gcs, ("animal",)), "animal")


@pytest.fixture(scope="session")
def auto_ckpt(tmp_path_factory):
    from ngc_gen.data.autogc.auto import auto_gcs

    from ..data.autogc.shapes import tubes

    mesh = tubes([((0, 0, 0), (0.6, 0, 0)), ((0.3, 0, 0), (0.3, 0.5, 0)),
                  ((0.6, 0, 0), (0.9, 0.3, 0))], [0.08, 0.06, 0.05])
    return _saved(tmp_path_factory, module_of([g.to_dict() for g in auto_gcs(mesh)],
                                              ("auto",)), "auto")


def export_config(run, out, *overrides):
    return compose_config("sample", ["mode=export", f"run={run}", f"out={out}",
                                     f"out_dir={out.parent}", *SMALL, *overrides])
