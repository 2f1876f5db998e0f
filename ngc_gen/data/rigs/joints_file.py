"""A plain joints file beside a mesh: rigs from tools that export no glTF skin.

```yaml
# horse.joints.yaml, beside horse.obj
mesh: horse.obj            # optional: default the file of the same stem beside it
joints:
  - {name: Hips, position: [0.0, 1.0, 0.0], parent: null}
  - {name: Spine, position: [0.0, 1.1, 0.4], parent: Hips}
```

Positions are in the mesh's coordinates at its rest pose. Without skin weights, each vertex
is bound rigidly to the bone nearest to it (the segment from a joint to each of its children
belongs to that joint; a joint without children is a point), which is what "skinned mainly to
a chain" needs. Such a rig has no clips: it poses at rest only.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import load_mesh, resolve_mesh_path

from .rig import Rig

JOINTS_SUFFIX = ".joints.yaml"
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb")


def _beside(path: Path) -> Path:
    stem = path.name[: -len(JOINTS_SUFFIX)] if path.name.endswith(JOINTS_SUFFIX) else path.stem
    for ext in MESH_SUFFIXES:
        if (path.parent / f"{stem}{ext}").is_file():
            return path.parent / f"{stem}{ext}"
    raise DataError(f"no mesh named {stem}.* beside the joints file", path=path, field="mesh",
                    fix=f"add 'mesh: <file>' or put {stem}.obj (or .ply, .stl, .off) beside it")


def nearest_bone(points: np.ndarray, heads: np.ndarray, tails: np.ndarray) -> np.ndarray:
    """(N,) index of the segment (heads[i], tails[i]) (S, 3) nearest to each point (N, 3)."""
    d = tails - heads
    L2 = np.maximum((d * d).sum(1), 1e-18)
    s = np.clip(np.einsum("nsk,sk->ns", points[:, None] - heads[None], d) / L2, 0.0, 1.0)
    foot = heads[None] + s[..., None] * d[None]
    return ((points[:, None] - foot) ** 2).sum(-1).argmin(1)


def load_joints_rig(path: str | os.PathLike, mesh: str | os.PathLike | None = None) -> Rig:
    """The rig of a joints file and its mesh (DataError naming the file and the joint)."""
    path = Path(path)
    src = os.fspath(path)
    if not path.is_file():
        raise DataError("joints file not found", path=src, fix="check the path")
    try:
        d = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError):
        raise DataError("malformed YAML", path=src, fix="write {mesh, joints: [{name, position, "
                                                         "parent}, ...]}") from None
    if not isinstance(d, dict) or not isinstance(d.get("joints"), list) or not d["joints"]:
        raise DataError("expected a mapping with a non-empty 'joints' list", path=src,
                        field="joints", fix="list the joints as {name, position, parent}")
    names, pos, parents = [], [], []
    for i, j in enumerate(d["joints"]):
        ok = isinstance(j, dict) and isinstance(j.get("name"), str) and isinstance(
            j.get("position"), list) and len(j["position"]) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in j["position"])
        if not ok:
            raise DataError(f"entry {i} needs a name and a position [x, y, z], got {j!r}"[:200],
                            path=src, field=f"joints[{i}]", fix="write {name, position, parent}")
        names.append(j["name"])
        pos.append([float(x) for x in j["position"]])
        parents.append(j.get("parent"))
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DataError(f"joint {dupes[0]!r} appears more than once", path=src, field="joints",
                        fix="give every joint a unique name")
    parent = np.full(len(names), -1)
    for i, p in enumerate(parents):
        if p is None:
            continue
        if p not in names:
            raise DataError(f"joint {names[i]!r} names parent {p!r}, which is not a joint",
                            path=src, field=f"joints[{i}].parent",
                            fix="name an existing joint or null for a root")
        parent[i] = names.index(p)
    P = np.asarray(pos)
    mesh_path = (resolve_mesh_path(mesh) if mesh is not None else
                 resolve_mesh_path(d["mesh"], path.parent) if isinstance(d.get("mesh"), str)
                 else _beside(path))
    m = load_mesh(mesh_path)
    V = np.asarray(m.vertices, np.float64)
    heads, tails, owner = [], [], []
    for j in range(len(names)):
        kids = np.flatnonzero(parent == j)
        for k in kids if len(kids) else [j]:
            heads.append(P[j]), tails.append(P[k]), owner.append(j)
    bone = nearest_bone(V, np.asarray(heads), np.asarray(tails))
    skin_joints = np.zeros((len(V), 4), np.int64)
    skin_joints[:, 0] = np.asarray(owner)[bone]
    weights = np.zeros((len(V), 4))
    weights[:, 0] = 1.0
    T = P.copy()
    T[parent >= 0] -= P[parent[parent >= 0]]
    ibm = np.tile(np.eye(4), (len(names), 1, 1))
    ibm[:, :3, 3] = -P
    return Rig(names=names, parent=parent, translation=T,
               rotation=np.tile([0.0, 0.0, 0.0, 1.0], (len(names), 1)), scale=np.ones((len(names), 3)),
               joints=np.arange(len(names)), inverse_bind=ibm, vertices=V,
               faces=np.asarray(m.faces, np.int64), skin_joints=skin_joints, skin_weights=weights,
               clips={}, source=src, oriented=False)
