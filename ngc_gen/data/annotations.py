"""GC annotation files: load, validate and save the YAML of docs/gcs.md.

```yaml
name: ant
mesh: ant.ply            # relative to this file, absolute, or a resource such as pyvista:ant.ply
normalize: {bound: 0.8}  # optional, default 0.8; false: the mesh is already in the GCs' frame
gcs: [ {name, curve: {type, points}, up, keys: [{t, radii, twist}], caps}, ... ]
frame: {up: [0, 1, 0], front: [0, 0, 1], from_mesh: [[3 x 3]], source: detected}  # optional
```

`frame` (written by a template transfer): the GCs and the mesh are in a body frame (up, front:
its axes), the mesh's coordinates turned by the rotation from_mesh before `normalize`.

GC coordinates are in the normalised frame (after ``normalize``; with ``normalize: false``, the
mesh's own coordinates, as in the ``edited.yaml`` that edit.py writes). Every problem raises
``DataError`` naming the file, the GC and the field, and saying how to fix it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ngc_gen.data.annotation_file import read_annotation_yaml
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.body_frame import frame_dict, read_frame
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import is_resource, resolve_mesh_path
from ngc_gen.geometry import GeneralizedCylinder, GeometryError
from ngc_gen.values import NumberError, is_number, read_number

# decoder_frame: written by sample.py beside re-centred GCs (read by conditioning, not by fits);
# frame: the body frame the shape is written in, and the rotation that writes the mesh in it
# (ngc_gen.data.body_frame, docs/gcs.md)
TOP_KEYS = {"name", "mesh", "normalize", "gcs", "decoder_frame", "frame"}
NORMALIZE_KEYS = {"bound"}
DEFAULT_BOUND = 0.8

# how to fix a geometry error, by the field GeometryError names
_GEOMETRY_FIXES = {
    "curve": "write the curve as {type: bezier|spline, points: [[x, y, z], ...]}",
    "curve.type": "use type 'bezier' or 'spline'",
    "curve.points": "give at least 2 distinct [x, y, z] points (a Bezier of degree n has n+1 "
    "control points); the curve must have non-zero length",
    "keys": "give a list of keys {t: 0..1, radii: [r_y, r_z], twist: degrees}, at least one",
    "caps": "give two positive cap lengths [l0, l1]",
    "up": "give up as [x, y, z], not parallel to the curve's start tangent",
}


@dataclass(eq=False)
class Annotation:
    """One shape: its mesh, normalisation and generalized cylinders.

    mesh: a resource (``pyvista:ant.ply``) or an absolute path (relative paths in a file are
    resolved against the file's folder on load). source: the YAML file it came from, if any.
    Compare annotations by ``to_dict()`` (GCs have no value equality).
    """

    name: str
    mesh: str
    gcs: list[GeneralizedCylinder]
    bound: float | None = DEFAULT_BOUND  # None: `normalize: false`, the mesh as it is
    source: Path | None = field(default=None, compare=False)
    frame: dict | None = None  # {up, front[, from_mesh, source]}: `body_frame.read_frame`

    def load_mesh(self):
        """(mesh, center, scale): the mesh in the GCs' frame (turned by `frame.from_mesh` when
        the frame records one, then normalised), with normalised = (turned - center) * scale."""
        import numpy as np
        import trimesh

        from ngc_gen.data.mesh.io import load_mesh, normalize

        mesh = load_mesh(self.mesh_path)
        if self.frame is not None and self.frame.get("from_mesh") is not None:
            R = np.asarray(self.frame["from_mesh"], np.float64)
            mesh = trimesh.Trimesh(np.asarray(mesh.vertices, np.float64) @ R.T,
                                   np.asarray(mesh.faces), process=False)
        return normalize(mesh, self.bound)

    @property
    def mesh_path(self) -> Path:
        """The mesh file on disk (a resource resolved inside its installed package)."""
        return resolve_mesh_path(self.mesh)

    @property
    def gc_names(self) -> list[str]:
        return [gc.name for gc in self.gcs]

    def to_dict(self, relative_to: str | os.PathLike | None = None) -> dict:
        """Plain YAML-safe dict. A file mesh path inside ``relative_to`` (a folder: the YAML's
        own) is written relative to it, so the folder can move with its meshes; any other mesh
        path is absolute, so the YAML can move (a run directory copied or renamed) and still
        find its mesh (a `../../meshes/cow.obj` broke whenever the run moved). Resources stay
        as written."""
        mesh = self.mesh
        if relative_to is not None and not is_resource(mesh):
            try:
                rel = os.path.relpath(mesh, os.fspath(relative_to))
            except ValueError:  # another drive on Windows: keep it absolute
                rel = None
            mesh = rel if rel is not None and Path(rel).parts[:1] != ("..",) \
                else os.path.abspath(mesh)
        d = {
            "name": self.name,
            "mesh": Path(mesh).as_posix() if not is_resource(mesh) else mesh,
            "normalize": False if self.bound is None else {"bound": float(self.bound)},
            "gcs": [gc.to_dict() for gc in self.gcs],
        }
        if self.frame is not None:
            d["frame"] = frame_dict(self.frame)
        return d

    def to_yaml(self, relative_to: str | os.PathLike | None = None) -> str:
        """YAML text of ``to_dict``; short lists inline so control points stay readable."""
        return yaml.safe_dump(self.to_dict(relative_to), sort_keys=False, default_flow_style=None, width=100)


def similar_gc_dict(d: dict, center, scale: float) -> dict:
    """A GC dict under the similarity x -> (x - center) * scale (what `normalize` applies to a
    mesh): control points move, radii and caps scale, up and twist do not, so the relative
    coordinates of a point and its image agree and the GC's codes stay valid."""
    import numpy as np

    c = np.asarray(center, np.float64)
    pts = (np.asarray(d["curve"]["points"], np.float64) - c) * float(scale)
    return {**d, "curve": {**d["curve"], "points": pts.tolist()},
            "keys": [{**k, "radii": [r * scale for r in k["radii"]]} for k in d["keys"]],
            "caps": [x * scale for x in d["caps"]]}


def rounded_gc_dict(d: dict, decimals: int = 7) -> dict:
    """A GC dict with its numbers rounded (readable YAML; 1e-7 is far below a voxel), in the
    field order of docs/gcs.md."""
    r = lambda x: float(round(float(x), decimals))  # noqa: E731
    return {"name": d["name"],
            "curve": {"type": d["curve"].get("type", "bezier"),
                      "points": [[r(x) for x in p] for p in d["curve"]["points"]]},
            "up": [r(x) for x in d["up"]],
            "keys": [{"t": r(k["t"]), "radii": [r(x) for x in k["radii"]],
                      "twist": r(k.get("twist", 0.0))} for k in d["keys"]],
            "caps": [r(x) for x in d["caps"]],
            **({"reparam": d["reparam"]} if d.get("reparam") is not None else {})}


def _is_number(x) -> bool:
    return is_number(x)


def _check_numbers(value, shape: tuple, path, gc: str, fld: str) -> None:
    """Check ``value`` is a list nest of numbers with ``shape`` (-1: any length, () a scalar)."""
    if not shape:
        try:
            read_number(value)
        except NumberError as e:  # the one rule for numbers (ngc_gen.values)
            raise DataError(e.what, path=path, gc=gc, field=fld, fix=e.fix) from None
        return
    if not isinstance(value, list) or (shape[0] != -1 and len(value) != shape[0]):
        want = "a list" if shape[0] == -1 else f"a list of {shape[0]}"
        raise DataError(f"expected {want}, got {value!r}", path=path, gc=gc, field=fld,
                        fix=f"write {fld} as {want} of numbers")
    for i, v in enumerate(value):
        _check_numbers(v, shape[1:], path, gc, f"{fld}[{i}]")


def _check_gc_types(d: dict, path, gc: str) -> None:
    """Type checks the geometry layer is lenient about (it calls float(), so True -> 1.0)."""
    curve = d.get("curve")
    if isinstance(curve, dict) and "points" in curve:
        _check_numbers(curve["points"], (-1, 3), path, gc, "curve.points")
    if d.get("up") is not None:
        _check_numbers(d["up"], (3,), path, gc, "up")
    if "caps" in d:
        _check_numbers(d["caps"], (2,), path, gc, "caps")
    keys = d.get("keys")
    if isinstance(keys, list):
        for i, k in enumerate(keys):
            if not isinstance(k, dict):
                continue  # geometry reports a non-mapping key with its own message
            for name in ("t", "twist"):
                if name in k:
                    _check_numbers(k[name], (), path, gc, f"keys[{i}].{name}")
            if "radii" in k:
                r = k["radii"]
                _check_numbers(r, () if _is_number(r) else (2,), path, gc, f"keys[{i}].radii")


def _parse_gc(d, index: int, path) -> GeneralizedCylinder:
    where = f"gcs[{index}]"
    if not isinstance(d, dict):
        raise DataError(f"each GC must be a mapping, got {type(d).__name__}", path=path, field=where,
                        fix="write each GC as {name, curve, up, keys, caps}")
    name = d.get("name")
    if not isinstance(name, str) or not name.strip():
        raise DataError(f"missing or empty GC name (got {name!r})", path=path, field=f"{where}.name",
                        fix="give every GC a unique string name")
    _check_gc_types(d, path, name)
    try:
        return GeneralizedCylinder.from_dict(d)
    except GeometryError as e:
        fix = _GEOMETRY_FIXES.get(e.field or "", None)
        if fix is None and e.field and e.field.startswith("keys"):
            fix = "give every key t in [0, 1], positive radii [r_y, r_z] and a finite twist"
        raise DataError(_strip_where(e), path=path, gc=e.gc_name or name, field=e.field,
                        fix=fix or "correct the GC entry (schema in docs/gcs.md)") from e


def _strip_where(e: GeometryError) -> str:
    """The GeometryError message without its "GC 'x', field 'y': " prefix (DataError adds its own)."""
    message = str(e)
    for prefix in (f"GC '{e.gc_name}', field '{e.field}': ", f"GC '{e.gc_name}': ", f"field '{e.field}': "):
        if message.startswith(prefix):
            return message[len(prefix):]
    return message


def annotation_from_dict(d, source: str | os.PathLike | None = None) -> Annotation:
    """Validate an annotation dict and build its GCs.

    source: the file the dict came from; it names errors and anchors a relative mesh path
    (without it a relative path is taken relative to the working directory).
    """
    path = None if source is None else Path(source)
    if not isinstance(d, dict):
        raise DataError(f"an annotation must be a mapping at the top level, got {type(d).__name__}",
                        path=path, fix="write keys name, mesh, normalize, gcs at the top level")
    unknown = set(d) - TOP_KEYS
    if unknown:
        raise DataError(f"unknown keys {sorted(unknown)}", path=path,
                        fix=f"use only {sorted(TOP_KEYS)} (check the spelling)")
    name = d.get("name", path.stem if path is not None else None)
    if not isinstance(name, str) or not name.strip():
        raise DataError(f"missing or empty shape name (got {name!r})", path=path, field="name",
                        fix="add 'name: <shape name>'")
    mesh = d.get("mesh")
    if not isinstance(mesh, str) or not mesh.strip():
        raise DataError(f"missing mesh (got {mesh!r})", path=path, field="mesh",
                        fix="add 'mesh: <file>' relative to the annotation, or a resource like pyvista:ant.ply")
    if not is_resource(mesh):
        mesh = os.path.abspath(resolve_mesh_path(mesh, path.parent if path is not None else None))
    norm = d.get("normalize", {})
    norm = {} if norm is None else norm
    if norm is not False and (not isinstance(norm, dict) or set(norm) - NORMALIZE_KEYS):
        raise DataError(f"normalize must be a mapping {{bound: number}} or false, got {norm!r}",
                        path=path, field="normalize",
                        fix="write 'normalize: {bound: 0.8}', 'normalize: false' (the mesh is "
                            "already in the GCs' frame) or leave it out")
    bound = None if norm is False else norm.get("bound", DEFAULT_BOUND)
    if bound is not None and (not _is_number(bound) or not 0 < bound < float("inf")):
        raise DataError(f"bound must be a positive number, got {bound!r}", path=path,
                        field="normalize.bound", fix="use e.g. 0.8 (the mesh then fits [-0.8, 0.8]^3)")
    gcs = d.get("gcs")
    if not isinstance(gcs, list) or not gcs:
        raise DataError(f"gcs must be a non-empty list of GCs, got {gcs!r}", path=path, field="gcs",
                        fix="add at least one GC, or delete the annotation to get an automatic GC")
    parsed = [_parse_gc(g, i, path) for i, g in enumerate(gcs)]
    names = [g.name for g in parsed]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise DataError(f"GC names {dupes} appear more than once", path=path, gc=dupes[0], field="name",
                        fix="give every GC a unique name")
    return Annotation(name=name, mesh=mesh, gcs=parsed,
                      bound=None if bound is None else float(bound), source=path,
                      frame=read_frame(d.get("frame"), path))


def load_annotation(path: str | os.PathLike) -> Annotation:
    """Read and validate an annotation YAML file (raises DataError with file/GC/field)."""
    path = Path(path)
    d = read_annotation_yaml(path)
    return annotation_from_dict(d, source=path)


def save_annotation(ann: Annotation, path: str | os.PathLike) -> Path:
    """Write ``ann`` as YAML atomically (temp file + os.replace); a mesh inside the new file's
    folder is written relative to it (the pair moves together), any other absolute (the YAML
    moves alone). Returns the path."""
    path = Path(path)
    return atomic_write_text(path, ann.to_yaml(relative_to=os.path.abspath(path.parent)))
