"""Writes datasets/animals/quadruped_transfer.yaml: the quadruped template (quadruped.yaml) with
where each part sits (`place`), averaged over the rig GCs of the twelve species at rest
(`data=animals data.split=rest`; the rigs are y-up and face +z).

    python datasets/tools/quadruped_transfer.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
import yaml

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.autogc.orient import Orientation
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import export_template
from ngc_gen.data.mesh.sampling import sample_surface
from ngc_gen.data.rigs.animals import Animals

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    conf = yaml.safe_load((ROOT / "conf/data/animals.yaml").read_text())
    conf = {k: v for k, v in conf.items() if not k.startswith("_")}
    conf.update(template=str(ROOT / "datasets/animals/quadruped.yaml"),
                rigs_dir=str(ROOT / ".cache/rigs"), out_dir=str(ROOT / ".cache/datasets/animals_f1"),
                frames=1, split="rest")
    y_up = Orientation(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), ("given", "given"))
    shapes = []
    for rec in Animals(**conf).build():
        ann = load_annotation(rec["annotation"])
        mesh = trimesh.load(rec["mesh"], process=False)
        pts, _ = sample_surface(mesh.vertices, mesh.faces, 20000, np.random.default_rng(0))
        shapes.append((ann.gcs, np.concatenate([mesh.vertices, pts]), y_up))
    t = export_template(shapes, "quadruped", load_template(conf["template"]))
    out = ROOT / "datasets/animals/quadruped_transfer.yaml"
    atomic_write_text(out, "# quadruped.yaml plus where each part sits (`place`: body frame front, left, up of\n"
                           "# the bounding box, over its half extents), averaged over the twelve species\n"
                           "# at rest; written by datasets/tools/quadruped_transfer.py. Transfer it onto\n"
                           "# your own meshes: python train.py stage=annotate data=folder data.path=DIR\n"
                           "# annotate.template=datasets/animals/quadruped_transfer.yaml\n" + t.to_yaml())
    print(out)


if __name__ == "__main__":
    main()
