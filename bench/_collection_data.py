"""The small-collection bench's training set: one 0 A.D. quadruped per species at rest
(ngc_gen.data.rigs.zeroad, docs/zeroad.md), each with the GCs its own rig gives for the
collection template (the names `train.py stage=annotate` writes), in a `data=folder` directory
that records the collection's body frame. Built once under .cache/bench/collection/."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = "datasets/animals/quadruped_transfer.yaml"  # what `experiment=collection` is given
FRAME = {"up": [0.0, 1.0, 0.0], "front": [0.0, 0.0, -1.0]}  # 0 A.D.'s meshes: y-up, facing -z


def training_folder(species: list[str], deb: str | None = None) -> Path:
    """<cache>/<species...>/: <mesh>.ply + <mesh>.yaml for the first kept mesh (by name) of
    each species; refuses a species the collection does not hold, naming those it does."""
    from ngc_gen.data.annotations import Annotation
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.rigs.zeroad import zeroad_quadrupeds

    out = ROOT / ".cache/bench/collection" / "_".join(species)
    out.mkdir(parents=True, exist_ok=True)
    meshes = sorted(zeroad_quadrupeds(ROOT / ".cache", deb=deb), key=lambda m: m.name)
    first = {}
    for m in meshes:
        first.setdefault(m.species, m)
    missing = sorted(set(species) - set(first))
    if missing:
        raise SystemExit(f"no 0 A.D. quadruped of species {missing}; choose from {sorted(first)}")
    template = None
    for s in species:
        m = first[s]
        ply, yml = out / f"{m.name}.ply", out / f"{m.name}.yaml"
        if yml.is_file():
            continue
        template = template or load_template(ROOT / TEMPLATE)
        mesh, gcs = _in_frame(m, template)
        mesh.export(ply)
        ann = Annotation(m.name, str(ply), gcs, frame=dict(FRAME))
        atomic_write_text(yml, ann.to_yaml(relative_to=out))
        print(f"training animal {m.name} ({s}): {len(gcs)} GCs", flush=True)
    return out


def _snap(v):
    """The coordinate axis (signed unit vector) nearest v."""
    import numpy as np

    i = int(np.argmax(np.abs(v)))
    out = np.zeros(3)
    out[i] = np.sign(v[i])
    return out


def _in_frame(m, template):
    """(mesh, GCs) of a 0 A.D. mesh at rest with its rig GCs, turned from its skeleton's own
    frame (snapped to the axes: most face -z, the sheep +z) into FRAME, so that every shape
    carries the template's up vectors (the rig's frame found by structure is a little off
    axis: 3e-4 on the giraffe)."""
    import numpy as np

    from ngc_gen.data.autogc.frame import moved_gcs, rotated_mesh
    from ngc_gen.geometry import GeneralizedCylinder

    up = _snap(m.joint_map.up)
    front = _snap(m.joint_map.front - (m.joint_map.front @ up) * up)
    own = np.stack([front, up, np.cross(up, front)])
    want = np.stack([FRAME["front"], FRAME["up"], np.cross(FRAME["up"], FRAME["front"])])
    R = want.T @ own  # R @ own front = FRAME front, R @ own up = FRAME up
    ps = replace(m, joint_map=replace(m.joint_map, up=up, front=front)).pose(template)
    gcs = [GeneralizedCylinder.from_dict(d) for d in ps.gcs]
    return rotated_mesh(ps.mesh, R), moved_gcs(gcs, R, np.zeros(3), 1.0)
