"""Writes datasets/animals/quadruped_transfer.yaml: the quadruped template (quadruped.yaml) with
where each part sits (`place`), averaged over the rig GCs of the twelve species at rest
(`data=animals data.split=rest`; the rigs are y-up and face +z), and where the rig ends each
part in the GC the transfer finds (`start_at`, `end_at`: ngc_gen/data/autogc/calibrate.py),
calibrated on the training split's posed animals (`data.split=train`: ten species, their
training clips) at frames 1-4 of 5, their triangles only. Frame 0, each clip's first, is what
bench/transfer.py measures on (data.frames=1): calibration and measurement share no mesh.

    python datasets/tools/quadruped_transfer.py     # ~7 min on 2 cores
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import trimesh
import yaml

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.autogc.calibrate import calibrate_ends
from ngc_gen.data.autogc.orient import Orientation
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import TransferSettings, export_template
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
    rig = load_template(conf["template"])
    # the parts every quadruped has: GCs carved out of another (a stag's antlers) stay the rig's
    base = dataclasses.replace(rig, gcs=tuple(g for g in rig.gcs if g.carve is None))

    def rig_gcs(rec) -> list:
        return [g for g in load_annotation(rec["annotation"]).gcs if g.name in base.names]

    shapes = []
    for rec in Animals(**conf).build():
        gcs = rig_gcs(rec)
        mesh = trimesh.load(rec["mesh"], process=False)
        pts, _ = sample_surface(mesh.vertices, mesh.faces, 20000, np.random.default_rng(0))
        shapes.append((gcs, np.concatenate([mesh.vertices, pts]), y_up))
    posed = {**conf, "out_dir": str(ROOT / ".cache/datasets/animals_f5"), "frames": 5,
             "split": "train"}
    annotated = [(rec["name"], trimesh.load(rec["mesh"], process=False), rig_gcs(rec))
                 for rec in Animals(**posed).build() if rec["frame"] > 0]
    t = export_template(shapes, "quadruped", base)
    print(f"calibrating the ends on {len(annotated)} posed animals", flush=True)
    t = calibrate_ends(t, annotated, TransferSettings.from_yaml(up="+y", front="+z"), workers=2)
    out = ROOT / "datasets/animals/quadruped_transfer.yaml"
    atomic_write_text(out, "# quadruped.yaml plus where each part sits (`place`: body frame front, left, up of\n"
                           "# the bounding box, over its half extents), averaged over the twelve species\n"
                           "# at rest, and where the rig ends each part in the GC the transfer finds\n"
                           "# (start_at, end_at: relative coordinates u, a, b, calibrated on the training\n"
                           "# split's posed animals); written by datasets/tools/quadruped_transfer.py.\n"
                           "# Transfer it onto your own meshes: python train.py stage=annotate\n"
                           "# data=folder data.path=DIR annotate.template=datasets/animals/quadruped_transfer.yaml\n"
                           + t.to_yaml())
    print(out)


if __name__ == "__main__":
    main()
