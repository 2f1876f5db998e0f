"""Blender (headless) imports an exported animal with a clip and correctives: one armature named
after the GCs, the mesh bound to it, the clip as an action, the shape keys, and Blender's
evaluated mesh at three clip times equals the file's own skinning + morph result within 1e-4 of
the bounding-box diagonal. Slow: Blender is large (make blender)."""
from __future__ import annotations

import pytest
import yaml

from ngc_gen.app.stages.sample import run_sample
from ngc_gen.export import Playback
from ngc_gen.export.blender import blender_available, blender_check

from .conftest import TEMPLATE_NAMES, export_config
from .test_export import _mini_rig

pytestmark = [pytest.mark.slow, pytest.mark.usefixtures("single_thread"),
              pytest.mark.skipif(not blender_available(), reason="no blender (make blender)")]


def test_blender_imports_the_animal(animal_ckpt, tmp_path):
    rig, tpl = tmp_path / "mini.glb", tmp_path / "mini.yaml"
    tpl.write_text(yaml.safe_dump(_mini_rig(rig, 60.0)))
    out = tmp_path / "animal.glb"
    run_sample(export_config(animal_ckpt, out, f"clip=rig:{rig}/Swing",
                             f"export.template={tpl}", "export.frames=5"))
    times = Playback(out).keyframes
    report = blender_check(out, list(TEMPLATE_NAMES.values()), 3,
                           [float(times[0]), float(times[2]) * 0.7, float(times[-1])])
    assert report["blender_ok"], report
    assert report["shape_keys"] == 5
