"""GC templates: which GCs every mesh of a collection gets (names, order, curve degrees, keys).

A generator needs one latent layout for a whole collection, so every mesh needs the same GCs.
A template YAML says which, once, for a whole family of meshes (a rig, a species, a category):

```yaml
version: 1
name: quadruped
gcs:
  - name: leg_fl              # GC name (unique); the order of `gcs` is the order in every shape
    joints: [FrontUpperLeg.L, FrontLowerLeg.L, IKFrontLeg.L, FF.L]  # chain the curve follows
    skinned: [FrontUpperLeg.L, FrontLowerLeg.L, IKFrontLeg.L, FF.L, FrontShoulder.L]
                              # joints whose skinned surface is this GC's (default: `joints`)
    degree: 3                 # Bezier degree of the curve (degree + 1 control points)
    keys: [0.0, 0.25, 0.5, 0.75, 1.0]  # t of the key frames (radii, twist)
    up: [0.0, 0.0, 1.0]       # frame up vector in the mesh's frame, the same in every shape
    extend: [false, true]     # extend the curve to the surface past its first / last joint
    parent: torso             # the GC it grows from (null: a root)
    attach: 0.9               # optional: t on the parent's curve where it attaches
    symmetric: leg_fr         # its mirror partner (null: none, or on the symmetry plane)
```

For transfer onto meshes without a rig (``autogc.transfer``) a template says where each part
sits instead of (or besides) its joints: `frame: {up: [0, 1, 0], front: [0, 0, 1]}` at the top
(the frame its `up` vectors are written in; default +z up, +x front) and per GC
`place: {start: [f, l, u], end: [f, l, u], radius: r}`: its curve's ends in the body frame
(front, left, up), centred on the surface's bounding box and divided by its half extents, and
its mean radius over the half length; optionally `start_at`, `end_at`: where the annotator's
curve ends sit in the GC the transfer finds, as relative coordinates [u, a, b] of that GC
(u = -1 / 1 its ends, a, b in its radii; docs/gcs.md), so a rig's leg starts at its hip inside
the body and a rig's head ends where its bone meets the face (`autogc.calibrate` measures them
on annotated meshes). `joints` may then be left out. `train.py
stage=annotate annotate.export_template=PATH` writes one from any annotated mesh.

Joint names may be glob patterns (`Tail*`, `Ear?.L`): a pattern in `joints` takes every
matching joint in hierarchy order (parents first), so rigs with 3 or 8 tail joints share one
template; a pattern in `skinned` may match nothing, a plain name must exist. Everything is
checked on load and a problem is a DataError naming the file, the GC and the field.
"""
from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.data.errors import DataError

TEMPLATE_VERSION = 1
TOP_KEYS = {"version", "name", "description", "gcs", "frame"}
GC_KEYS = {"name", "joints", "skinned", "degree", "keys", "up", "extend", "parent", "attach",
           "symmetric", "place", "carve"}
AT_KEYS = ("start_at", "end_at")  # place's optional calibrated ends (autogc.calibrate)
PLACE_KEYS = {"start", "end", "radius", *AT_KEYS}
DEFAULT_FRAME = {"up": (0.0, 0.0, 1.0), "front": (1.0, 0.0, 0.0)}
_GLOB = set("*?[")


def is_pattern(name: str) -> bool:
    return bool(_GLOB & set(name))


@dataclass(frozen=True)
class TemplateGC:
    """One GC of a template (fields as in the module docstring)."""

    name: str
    joints: tuple[str, ...]
    skinned: tuple[str, ...] = ()
    degree: int = 3
    keys: tuple[float, ...] = (0.0, 0.25, 0.5, 0.75, 1.0)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    extend: tuple[bool, bool] = (False, True)
    parent: str | None = None
    attach: float | None = None
    symmetric: str | None = None
    place: dict | None = None  # {start: (3,), end: (3,), radius: float} (module docstring)
    carve: dict | None = None  # {from: GC name, side: (3,) or None} (module docstring)

    def to_dict(self) -> dict:
        d = {"name": self.name, "joints": list(self.joints), "skinned": list(self.skinned),
             "degree": self.degree, "keys": [float(t) for t in self.keys],
             "up": [float(x) for x in self.up], "extend": list(self.extend),
             "parent": self.parent, "symmetric": self.symmetric}
        if self.attach is not None:
            d["attach"] = float(self.attach)
        if self.place is not None:
            d["place"] = {"start": [round(float(x), 5) for x in self.place["start"]],
                          "end": [round(float(x), 5) for x in self.place["end"]],
                          "radius": round(float(self.place["radius"]), 5)}
            d["place"].update({k: [round(float(x), 5) for x in self.place[k]]
                               for k in AT_KEYS if k in self.place})
        if self.carve is not None:
            d["carve"] = {"from": self.carve["from"], "side": None if self.carve["side"] is None
                          else [float(x) for x in self.carve["side"]]}
            del d["joints"], d["skinned"], d["extend"]
        return d


@dataclass(frozen=True)
class Template:
    """A named, versioned list of template GCs; `source`: the file it came from."""

    name: str
    gcs: tuple[TemplateGC, ...]
    version: int = TEMPLATE_VERSION
    source: str | None = None
    frame: dict | None = None  # {up: (3,), front: (3,)}; None: DEFAULT_FRAME

    @property
    def up(self) -> np.ndarray:
        return np.asarray((self.frame or DEFAULT_FRAME)["up"], dtype=np.float64)

    @property
    def front(self) -> np.ndarray:
        return np.asarray((self.frame or DEFAULT_FRAME)["front"], dtype=np.float64)

    @property
    def placed(self) -> bool:
        """Every GC says where it sits (`place`): the template can be transferred."""
        return all(g.place is not None for g in self.gcs)

    @property
    def names(self) -> list[str]:
        return [g.name for g in self.gcs]

    @property
    def root(self) -> str:
        """The name of the GC with no parent (the torso): the one every chain hangs from."""
        return next(g.name for g in self.gcs if g.parent is None)

    def gc(self, name: str) -> TemplateGC:
        if name not in self.names:
            raise DataError(f"template has no GC {name!r}", path=self.source, field="gcs",
                            fix=f"use one of {self.names}")
        return self.gcs[self.names.index(name)]

    def to_dict(self) -> dict:
        d = {"version": self.version, "name": self.name}
        if self.frame is not None:
            d["frame"] = {k: [float(x) for x in v] for k, v in self.frame.items()}
        return {**d, "gcs": [g.to_dict() for g in self.gcs]}

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None, width=100)

    def resolve_joints(self, joint_names: list[str], depth: list[int] | np.ndarray,
                       rig: str | os.PathLike | None = None) -> dict[str, dict[str, list[int]]]:
        """Per GC {chain: [joint index, ...], skinned: [...]} in a rig with `joint_names`
        (J,) at hierarchy `depth` (J,). DataError naming the rig file, the GC and the joint
        when a chain joint is missing, or when a joint is claimed by two GCs."""
        order = sorted(range(len(joint_names)), key=lambda j: (int(depth[j]), j))
        where = os.fspath(rig) if rig is not None else None

        def match(pattern: str, gc: str, fld: str, required: bool) -> list[int]:
            if not is_pattern(pattern):
                if pattern in joint_names:
                    return [joint_names.index(pattern)]
                raise DataError(f"rig has no joint {pattern!r} (template "
                                f"{self.source or self.name})", path=where, gc=gc, field=fld,
                                fix="rename the joint in the template to one of the rig's "
                                    f"joints ({', '.join(joint_names[:10])}, ...) or use a "
                                    "pattern such as 'Tail*'")
            hits = [j for j in order if fnmatch.fnmatchcase(joint_names[j], pattern)]
            if not hits and required:
                raise DataError(f"no joint of the rig matches {pattern!r} (template "
                                f"{self.source or self.name})", path=where, gc=gc, field=fld,
                                fix="give a pattern that matches the rig's joint names")
            return hits

        out: dict[str, dict[str, list[int]]] = {}
        owner: dict[int, str] = {}
        for g in self.gcs:
            if g.carve is not None:  # its surface is carved out of another GC's (pose_shape)
                out[g.name] = {"chain": [], "skinned": []}
                continue
            if not g.joints:
                raise DataError(f"template GC has no joints (template {self.source or self.name})",
                                path=where, gc=g.name, field="joints",
                                fix="a template without joints is for transfer (train.py "
                                    "stage=annotate annotate.template=...); list the rig's joints "
                                    "to pose it on a rig")
            chain = [j for p in g.joints for j in match(p, g.name, "joints", True)]
            skinned = ([j for p in g.skinned for j in match(p, g.name, "skinned", False)]
                       if g.skinned else chain)
            for j in dict.fromkeys(skinned):
                if j in owner and owner[j] != g.name:
                    raise DataError(f"joint {joint_names[j]!r} is claimed by GCs {owner[j]!r} "
                                    f"and {g.name!r}", path=self.source, gc=g.name,
                                    field="skinned", fix="give every joint to one GC")
                owner[j] = g.name
            out[g.name] = {"chain": list(dict.fromkeys(chain)), "skinned": list(dict.fromkeys(skinned))}
        return out


def _fail(what, path, gc=None, fld=None, fix=None):
    raise DataError(what, path=path, gc=gc, field=fld, fix=fix)


def _names(value, path, gc, fld, allow_empty: bool) -> tuple[str, ...]:
    if value is None and allow_empty:
        return ()
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value) \
            or (not value and not allow_empty):
        _fail(f"expected a list of joint names, got {value!r}", path, gc, fld,
              "write joint names as a YAML list, e.g. [Neck1, Neck2] or ['Tail*']")
    return tuple(value)


def _vec3(v) -> bool:
    return isinstance(v, (list, tuple)) and len(v) == 3 and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v)


def _place(p, path, gc) -> dict | None:
    if p is None:
        return None
    if not (isinstance(p, dict) and {"start", "end", "radius"} <= set(p) <= PLACE_KEYS
            and _vec3(p["start"]) and _vec3(p["end"]) and isinstance(p["radius"], (int, float))
            and not isinstance(p["radius"], bool) and p["radius"] > 0
            and all(_vec3(p[k]) for k in AT_KEYS if k in p)):
        _fail(f"place must be {{start: [f, l, u], end: [f, l, u], radius: r > 0}} (optionally "
              f"start_at, end_at: [u, a, b]), got {p!r}",
              path, gc, "place", "write it with train.py stage=annotate annotate.export_template=PATH")
    out = {"start": tuple(float(x) for x in p["start"]), "end": tuple(float(x) for x in p["end"]),
           "radius": float(p["radius"])}
    out.update({k: tuple(float(x) for x in p[k]) for k in AT_KEYS if k in p})
    return out


def _carve(c, path, gc) -> dict | None:
    if c is None:
        return None
    ok = isinstance(c, dict) and set(c) <= {"from", "side"} and isinstance(c.get("from"), str)
    side = c.get("side") if ok else None
    if ok and side is not None:
        ok = _vec3(side) and np.linalg.norm(side) > 0
    if not ok:
        _fail(f"carve must be {{from: <GC name>, side: [x, y, z] or null}}, got {c!r}", path, gc,
              "carve", "e.g. carve: {from: head, side: [1, 0, 0]}")
    return {"from": c["from"], "side": None if side is None else
            tuple(float(x) / float(np.linalg.norm(side)) for x in side)}


def _frame(f, path) -> dict | None:
    if f is None:
        return None
    ok = isinstance(f, dict) and set(f) == {"up", "front"} and _vec3(f["up"]) and _vec3(f["front"])
    if ok:
        up, front = np.asarray(f["up"], float), np.asarray(f["front"], float)
        ok = np.linalg.norm(up) > 0 and np.linalg.norm(front) > 0 and abs(
            up @ front) < 1e-6 * np.linalg.norm(up) * np.linalg.norm(front)
    if not ok:
        _fail(f"frame must be {{up: [x, y, z], front: [x, y, z]}}, two orthogonal directions, "
              f"got {f!r}", path, fld="frame", fix="e.g. frame: {up: [0, 1, 0], front: [0, 0, 1]}")
    return {k: tuple(float(x) / float(np.linalg.norm(f[k])) for x in f[k]) for k in ("up", "front")}


def template_from_dict(d, source: str | os.PathLike | None = None) -> Template:
    """Validate a template dict (DataError naming `source`, the GC and the field)."""
    path = None if source is None else os.fspath(source)
    if not isinstance(d, dict):
        _fail(f"a template must be a mapping at the top level, got {type(d).__name__}", path,
              fix="write keys version, name, gcs at the top level")
    unknown = set(d) - TOP_KEYS
    if unknown:
        _fail(f"unknown keys {sorted(unknown)}", path, fix=f"use only {sorted(TOP_KEYS)}")
    version = d.get("version")
    if version != TEMPLATE_VERSION:
        _fail(f"template version {version!r} is not supported", path, fld="version",
              fix=f"write 'version: {TEMPLATE_VERSION}' (the format of this release)")
    name = d.get("name", Path(path).stem if path else None)
    if not isinstance(name, str) or not name.strip():
        _fail(f"missing or empty template name (got {name!r})", path, fld="name",
              fix="add 'name: <template name>'")
    gcs = d.get("gcs")
    if not isinstance(gcs, list) or not gcs:
        _fail("gcs must be a non-empty list", path, fld="gcs", fix="list the GCs of the template")
    out = [_template_gc(g, i, path) for i, g in enumerate(gcs)]
    _check_links(out, path)
    return Template(name, tuple(out), int(version), path, _frame(d.get("frame"), path))


def _template_gc(g, i: int, path: str | None) -> TemplateGC:
    """Template GC i checked (DataError naming the file, the GC and the field)."""
    if not isinstance(g, dict):
        _fail(f"each GC must be a mapping, got {type(g).__name__}", path, fld=f"gcs[{i}]")
    gname = g.get("name")
    if not isinstance(gname, str) or not gname.strip():
        _fail(f"missing GC name (got {gname!r})", path, fld=f"gcs[{i}].name",
              fix="give every GC a unique name")
    bad = set(g) - GC_KEYS
    if bad:
        _fail(f"unknown keys {sorted(bad)}", path, gname, fix=f"use only {sorted(GC_KEYS)}")
    carve = _carve(g.get("carve"), path, gname)
    if carve is not None and any(k in g for k in ("joints", "skinned", "extend")):
        _fail("a carved GC takes its surface from another GC; it has no joints, skinned or "
              "extend", path, gname, "carve", "remove joints, skinned and extend, or carve")
    joints = _names(g.get("joints"), path, gname, "joints", "place" in g or carve is not None)
    place = _place(g.get("place"), path, gname)
    skinned = _names(g.get("skinned"), path, gname, "skinned", True)
    degree = g.get("degree", 3)
    if not isinstance(degree, int) or isinstance(degree, bool) or not 1 <= degree <= 7:
        _fail(f"degree must be an integer 1..7, got {degree!r}", path, gname, "degree",
              "use 3 (a cubic) unless the part is straight (1) or gently bent (2)")
    keys = g.get("keys", [0.0, 0.25, 0.5, 0.75, 1.0])
    if not isinstance(keys, list) or not keys or not all(
            isinstance(t, (int, float)) and not isinstance(t, bool) and 0.0 <= t <= 1.0
            for t in keys) or list(keys) != sorted(keys) or len(set(keys)) != len(keys):
        _fail(f"keys must be increasing numbers in [0, 1], got {keys!r}", path, gname, "keys",
              "e.g. keys: [0.0, 0.25, 0.5, 0.75, 1.0]")
    up = g.get("up", [0.0, 0.0, 1.0])
    if not (isinstance(up, list) and len(up) == 3 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in up)) \
            or not np.linalg.norm(up) > 0:
        _fail(f"up must be a non-zero [x, y, z], got {up!r}", path, gname, "up",
              "give a direction normal to the part's usual direction")
    extend = g.get("extend", [False, True])
    if not (isinstance(extend, list) and len(extend) == 2 and all(isinstance(e, bool) for e in extend)):
        _fail(f"extend must be [bool, bool], got {extend!r}", path, gname, "extend",
              "e.g. [false, true]: the start attaches, the end is free")
    attach = g.get("attach")
    if attach is not None and not (isinstance(attach, (int, float)) and 0.0 <= attach <= 1.0):
        _fail(f"attach must be a t in [0, 1] or null, got {attach!r}", path, gname, "attach")
    for fld in ("parent", "symmetric"):
        v = g.get(fld)
        if v is not None and not isinstance(v, str):
            _fail(f"{fld} must be a GC name or null, got {v!r}", path, gname, fld)
    return TemplateGC(gname, joints, skinned, int(degree), tuple(float(t) for t in keys),
                      tuple(float(x) for x in up), tuple(extend), g.get("parent"),
                      None if attach is None else float(attach), g.get("symmetric"), place, carve)


def _check_links(out: list[TemplateGC], path: str | None) -> None:
    """Names unique; parent, symmetric and carve.from name GCs of the template; parents a tree."""
    names = [g.name for g in out]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        _fail(f"GC names {dupes} appear more than once", path, dupes[0], "name",
              "give every GC a unique name")
    for g in out:
        for fld in ("parent", "symmetric"):
            v = getattr(g, fld)
            if v is not None and v not in names:
                _fail(f"{fld} {v!r} is not a GC of the template", path, g.name, fld,
                      f"use one of {names} or null")
        if g.symmetric is not None and out[names.index(g.symmetric)].symmetric != g.name:
            _fail(f"symmetric partner {g.symmetric!r} does not name {g.name!r} back", path,
                  g.name, "symmetric", "give both GCs of a pair each other's name")
    for i, g in enumerate(out):
        if g.carve is None:
            continue
        src = g.carve["from"]
        if src not in names[:i] or out[names.index(src)].carve is not None:
            _fail(f"carve.from {src!r} must be an earlier GC of the template that is not itself "
                  "carved", path, g.name, "carve", f"use one of {names[:i]}")
    for g in out:  # parents form a tree
        seen, p = {g.name}, g.parent
        while p is not None:
            if p in seen:
                _fail(f"parent chain loops through {p!r}", path, g.name, "parent",
                      "make the parents a tree with one or more roots (parent: null)")
            seen.add(p)
            p = out[names.index(p)].parent


def load_template(path: str | os.PathLike) -> Template:
    """Read and validate a template YAML file."""
    path = Path(path)
    if not path.is_file():
        raise DataError("template file not found", path=path,
                        fix="check the path (the shipped one: datasets/animals/quadruped.yaml)")
    try:
        d = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        mark = getattr(e, "problem_mark", None)
        at = f" at line {mark.line + 1}" if mark is not None else ""
        raise DataError(f"malformed YAML{at}", path=path, fix="correct the YAML syntax") from None
    return template_from_dict(d, path)
