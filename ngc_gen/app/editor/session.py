"""The editor's document and state machine, with no GUI (docs/editor.md).

The document IS an edit program: a list of op dicts as `conf/edit/*.yaml` writes them. Every
interaction builds one op from what the user set (a control point's new position, a key's
radius or twist, a stretch factor, a pose angle, a part mix) against the shape as it was before
that op, and appends it, or updates the last op when it continues the same interaction (the
same control point dragged again, the same slider moved again). A new document is accepted only
if the whole program applies to the base shape (`EditProgram.from_dict` + `apply_to`) and the
GCs it changed stay within the editor's `Limits`; otherwise document and shape stay as they were
and the outcome says why. Undo and redo step through documents, one op per step. `save` writes
the program that `edit.py program_file=...` replays to the same mesh.

Thread-safe: the viewer calls it from its callback threads; meshes are extracted outside the
lock from a `snapshot`.
"""
from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError
from ngc_gen.edit import EditError, EditProgram
from ngc_gen.geometry import GeometryError
from ngc_gen.shape import Shape
from ngc_gen.shape.mixing import start_frame

from .library import ShapeLibrary
from .limits import Limits, check

#: errors that make an interaction a refusal (anything else is a bug, reported the same way so
#: the viewer keeps running, but named as internal)
REFUSALS = (EditError, GeometryError, DataError, ValueError, KeyError)
POSE_AXES = ("normal", "binormal")


@dataclass(frozen=True)
class Outcome:
    """What an interaction did: ok (accepted), a one-line message, files written."""

    ok: bool
    message: str
    paths: tuple[Path, ...] = ()

    def __bool__(self) -> bool:
        return self.ok


def _floats(x) -> list:
    """Plain Python floats (nested lists) for YAML that round-trips exactly."""
    return np.asarray(x, dtype=np.float64).tolist()


class EditorSession:
    """An edit program being built on shape `shape` of `library`.

    limits: what the editor refuses (`Limits`); pose_at: the handle region [t_a, t_b] a pose
    turns; bound, chunk: the extraction box and network rows per call of `mesh`; name,
    description, smooth_union: the program's; ops: an initial document (validated)."""

    def __init__(self, library: ShapeLibrary, shape: str, limits: Limits, *, pose_at, chunk: int,
                 name: str = "edited", description: str = "", smooth_union: float = 0.0,
                 ops=()):
        self.library, self.limits = library, limits
        self.pose_at = (float(pose_at[0]), float(pose_at[1]))
        self.chunk = int(chunk)
        self.name, self.description = str(name), str(description)
        self.smooth_union = float(smooth_union)
        self.base = library[shape]
        self.shape = self.base.replaced(smooth=self.smooth_union)
        self._ops: list[dict] = []
        self._undo: list[list[dict]] = []
        self._redo: list[list[dict]] = []
        self._merge: tuple | None = None   # the interaction the last op belongs to
        self._pre = self.shape             # the shape before the last op
        self._lock = threading.RLock()
        self._meshes: dict[tuple, object] = {}
        self.version = 0
        self.message = f"opened shape '{shape}'"
        if ops:
            self.shape = self._apply(list(ops), self.base)
            self._ops = [dict(o) for o in ops]
            self.message += f" with {len(self._ops)} ops"

    # ---- state ----------------------------------------------------------------------------------
    @property
    def ops(self) -> list[dict]:
        with self._lock:
            return [dict(o) for o in self._ops]

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)

    def continues(self, key: tuple) -> bool:
        """True if an interaction with this key would update the last op (a relative control,
        like a stretch factor or a pose angle, then starts from the last op's value)."""
        with self._lock:
            return self._merge == key and bool(self._ops)

    def snapshot(self) -> tuple[int, Shape]:
        """(version, shape) of the current document, consistent with each other."""
        with self._lock:
            return self.version, self.shape

    def program(self) -> dict:
        """The document as an edit program dict (what `save` writes)."""
        with self._lock:
            return self._program(self._ops, self.base)

    def _program(self, ops: list[dict], base: Shape) -> dict:
        return {"name": self.name, "description": self.description, "shape": base.name,
                "smooth_union": self.smooth_union, "ops": [dict(o) for o in ops]}

    # ---- applying and accepting -----------------------------------------------------------------
    def _apply(self, ops: list[dict], base: Shape) -> Shape:
        """The base shape after `ops` (EditError etc. if the program does not apply)."""
        if not ops:
            return base.replaced(smooth=self.smooth_union)
        program = EditProgram.from_dict(self._program(ops, base), source="editor")
        return program.apply_to(base, self.library.resolver(base))

    def _try(self, ops: list[dict], base: Shape, limits: bool = True
             ) -> tuple[Shape | None, str]:
        """(shape, warnings) if `ops` apply to `base` (and, with `limits`, the GCs they change
        from the current shape stay within the limits), else (None, why)."""
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                shape = self._apply(ops, base)
        except REFUSALS as e:
            return None, str(e)
        except Exception as e:  # a bug must not take the editor down: refuse and say so
            return None, f"internal error ({type(e).__name__}: {e})"
        why = check(self.shape.gcs, shape.gcs, self.limits) if limits else None
        if why is not None:
            return None, why
        return shape, "; ".join(str(w.message) for w in caught)

    def _accept(self, ops: list[dict], shape: Shape, message: str) -> Outcome:
        self._ops, self.shape = ops, shape
        self.version += 1
        self.message = message
        return Outcome(True, message)

    def _refuse(self, message: str) -> Outcome:
        self.message = f"refused: {message}"
        return Outcome(False, self.message)

    def _reference(self, key: tuple) -> Shape:
        """The shape an interaction's op is computed against: the shape before the last op if
        the interaction continues it, else the current shape."""
        return self._pre if self._merge == key and self._ops else self.shape

    def interact(self, op: dict, key: tuple) -> Outcome:
        """Append `op`, or replace the last op when it belongs to the same interaction `key`;
        accepted only if the new program applies within the limits. The ops before it are
        not re-run: `op` applies to the shape they made (the current shape, or the one before
        the last op when updating it), which is what running the whole program gives, since
        ops are deterministic functions of the shape before them (the replay tests check it);
        so an interaction costs one op whatever the program's length."""
        with self._lock:
            merging = self._merge == key and bool(self._ops)
            ops = (self._ops[:-1] if merging else list(self._ops)) + [dict(op)]
            shape, note = self._try([dict(op)], self._pre if merging else self.shape)
            if shape is None:
                return self._refuse(note)
            if not merging:
                self._undo.append(self._ops)
                self._redo.clear()
                self._pre, self._merge = self.shape, key
            what = f"{'updated' if merging else 'added'} ops[{len(ops) - 1}]: {describe(op)}"
            return self._accept(ops, shape, what + (f" ({note})" if note else ""))

    def _step(self, source: list, target: list, verb: str) -> Outcome:
        with self._lock:
            if not source:
                return self._refuse(f"nothing to {verb}")
            ops = source[-1]
            shape, note = self._try(ops, self.base)
            if shape is None:
                return self._refuse(f"cannot {verb}: {note}")
            source.pop()
            target.append(self._ops)
            self._merge = None
            return self._accept(ops, shape, f"{verb}: {len(ops)} ops")

    def undo(self) -> Outcome:
        return self._step(self._undo, self._redo, "undo")

    def redo(self) -> Outcome:
        return self._step(self._redo, self._undo, "redo")

    def open(self, name: str) -> Outcome:
        """Make library shape `name` the base; the program is kept if it applies to it, else
        the document starts empty (history cleared)."""
        with self._lock:
            try:
                base = self.library[name]
            except EditError as e:
                return self._refuse(str(e))
            shape, note = self._try(self._ops, base, limits=False)
            self.base, self._merge = base, None
            if shape is None:
                kept = len(self._ops)
                self._undo.clear()
                self._redo.clear()
                return self._accept([], base.replaced(smooth=self.smooth_union),
                                    f"opened '{name}'; its {kept} ops did not apply ({note}), "
                                    "so the program starts empty")
            return self._accept(self._ops, shape, f"opened '{name}' with {len(self._ops)} ops")

    # ---- interactions ---------------------------------------------------------------------------
    def _gc(self, shape: Shape, gc: str):
        return shape.gcs[shape.index(gc)]

    def _key(self, shape: Shape, gc: str, key: int):
        keys = self._gc(shape, gc).keys
        if not 0 <= int(key) < len(keys):
            raise KeyError(f"GC '{gc}' has keys 0..{len(keys) - 1}, not {key}")
        return keys[int(key)]

    def _guarded(self, build) -> Outcome:
        """Run an op builder; a bad reference (unknown GC, key, point) is a refusal."""
        with self._lock:
            try:
                op, key = build()
            except REFUSALS as e:
                return self._refuse(str(e).strip("'\""))
            return self.interact(op, key)

    def move_point(self, gc: str, index: int, position) -> Outcome:
        """Put control point `index` of `gc` at `position` (3,): op `move` with the offset from
        where the point was before this drag."""
        def build():
            key = ("move", gc, int(index))
            pts = self._gc(self._reference(key), gc).curve.points
            if not -len(pts) <= int(index) < len(pts):
                raise KeyError(f"GC '{gc}' has control points 0..{len(pts) - 1}, not {index}")
            offset = np.asarray(position, dtype=np.float64).reshape(3) - pts[int(index)]
            return {"op": "move", "gc": gc, "indices": [int(index)],
                    "offsets": [_floats(offset)]}, key
        return self._guarded(build)

    def set_radius(self, gc: str, key: int, radius: float) -> Outcome:
        """Make the mean radius (r_y + r_z) / 2 of key `key` of `gc` equal `radius`: op `scale`
        at the key's t by radius / (mean radius before this slider move)."""
        def build():
            k = self._key(self.shape, gc, key)
            ref = self._key(self._reference(("scale", gc, k.t)), gc, key)
            factor = float(radius) / (0.5 * (ref.radii[0] + ref.radii[1]))
            return {"op": "scale", "gc": gc, "t": float(k.t), "factor": factor}, \
                ("scale", gc, k.t)
        return self._guarded(build)

    def set_twist(self, gc: str, key: int, degrees: float) -> Outcome:
        """Make the twist of key `key` of `gc` equal `degrees`: op `twist` at the key's t."""
        def build():
            k = self._key(self.shape, gc, key)
            ref = self._key(self._reference(("twist", gc, k.t)), gc, key)
            return {"op": "twist", "gc": gc, "t": float(k.t),
                    "degrees": float(degrees) - float(ref.twist)}, ("twist", gc, k.t)
        return self._guarded(build)

    def stretch(self, gc: str, t0: float, t1: float, factor: float) -> Outcome:
        """Make the network's t-range [t0, t1] of `gc` `factor` times longer (op `stretch`)."""
        def build():
            self._gc(self.shape, gc)
            return {"op": "stretch", "gc": gc, "t0": float(t0), "t1": float(t1),
                    "factor": float(factor)}, ("stretch", gc, float(t0), float(t1))
        return self._guarded(build)

    def pose(self, gc: str, axis: str, degrees: float) -> Outcome:
        """Pose a limb: turn the handle region `pose_at` of `gc` by `degrees` about its start
        (op `handles`), about the start frame's normal or binormal; the GCs that hold the
        limb's start stay fixed."""
        def build():
            if axis not in POSE_AXES:
                raise KeyError(f"pose axis must be one of {POSE_AXES}, not {axis!r}")
            key = ("pose", gc, axis)
            ref = self._reference(key)
            g = self._gc(ref, gc)
            frame = start_frame(g)
            vec = frame[2] if axis == "normal" else frame[3]
            fixed = [o.name for o in ref.gcs
                     if o.name != gc and bool(o.contains(frame[:1])[0])]
            op = {"op": "handles", "gc": gc, "at": list(self.pose_at),
                  "rotate": {"axis": _floats(vec), "degrees": float(degrees),
                             "pivot": {"gc": gc, "t": 0.0}}}
            if fixed:
                op["fixed"] = fixed
            return op, key
        return self._guarded(build)

    def mix(self, gc: str, source: str, source_gc: str | None = None, blend: str = "replace",
            geometry: str = "source", **blend_params) -> Outcome:
        """Part mixing (op `mix`): GC `gc` takes GC `source_gc` (default: the same name) of
        library shape `source` with a blend (t0, t1 or w as the blend needs)."""
        def build():
            ref, j = self._reference(("mix", gc)), self.shape.index(gc)
            if j in ref.mixes and ref.mixes[j] is not self.base.mixes.get(j):
                raise EditError("this GC is already mixed by an earlier op", op="mix", gc=gc,
                                fix="mix each GC once (one source and one blend per GC); "
                                    "undo the earlier mix to change it")
            op = {"op": "mix", "gc": gc,
                  "source": {"shape": source, "gc": source_gc or gc},
                  "blend": blend, "geometry": geometry,
                  **{k: float(v) for k, v in blend_params.items() if v is not None}}
            return op, ("mix", gc)
        return self._guarded(build)

    # ---- outputs --------------------------------------------------------------------------------
    def mesh(self, resolution: int, shape: Shape | None = None, version: int | None = None,
             **extract_kw):
        """ExtractionResult of the current shape (or a snapshot's) on a resolution^3 grid over
        the limits' box; extract_kw go to `Shape.mesh` (the default is the exact path edit.py
        takes, so an exported mesh is edit.py's). Network calls take at most `chunk` rows,
        fewer on small grids (`auto_chunk`; values do not depend on it). The last few results
        are kept per (version, resolution, extract_kw)."""
        from ngc_gen.generate import auto_chunk

        if shape is None:
            version, shape = self.snapshot()
        key = (version, int(resolution), repr(sorted(extract_kw.items())))
        if version is not None and key in self._meshes:
            return self._meshes[key]
        extract_kw.setdefault("chunk", min(self.chunk, auto_chunk(resolution)))
        result = shape.mesh(int(resolution), self.limits.bound, **extract_kw)
        if version is not None:
            with self._lock:
                self._meshes[key] = result
                while len(self._meshes) > 4:
                    self._meshes.pop(next(iter(self._meshes)))
        return result

    def sources(self) -> list[str]:
        """Shape names the program refers to: the base and every mix source."""
        with self._lock:
            names = [self.base.name]
            for o in self._ops:
                if o["op"] == "mix":
                    src = o["source"]
                    names.append((src if isinstance(src, str) else src.get("shape"))
                                 or self.base.name)
            return list(dict.fromkeys(names))

    def save(self, path, resolution: int) -> Outcome:
        """Write the program YAML (and, for a shape no checkpoint holds, a checkpoint beside
        it named <stem>.shapes.ckpt); the header says how to replay it with edit.py."""
        path = Path(path)
        with self._lock:
            if not self._ops:
                return self._refuse("nothing to save: the program has no ops yet")
            program, names = self.program(), self.sources()
            written = []
            ckpt = self.library.checkpoint
            if self.library.needs_checkpoint(names):
                ckpt = self.library.write_checkpoint(path.with_suffix(".shapes.ckpt"), names,
                                                     source="editor")
                written.append(ckpt)
            header = (f"# Edit program made in the editor on shape '{self.base.name}'.\n"
                      f"# Replay: python edit.py run={ckpt} program_file={path} "
                      f"extract.resolution={int(resolution)}\n")
            atomic_write_text(path, header + yaml.safe_dump(program, sort_keys=False,
                                                            default_flow_style=None, width=100))
            written.append(path)
            self.message = f"saved {path}"
            return Outcome(True, self.message, tuple(written))

    def export_mesh(self, path, resolution: int) -> Outcome:
        """Write the current mesh at `resolution` as PLY."""
        path = Path(path)
        mesh = self.mesh(resolution).mesh
        atomic_write(path, lambda f: f.write(mesh.export(file_type="ply")))
        self.message = f"exported {len(mesh.faces)} faces to {path}"
        return Outcome(True, self.message, (path,))


    def export_glb(self, path, resolution: int, parents: dict | None = None) -> Outcome:
        """Write the current shape at `resolution` as a rigged glTF binary through the
        exporter `sample.py mode=export` runs (`ngc_gen.export.export_shape`, its other
        settings conf/mode/export.yaml's): the mesh `export_mesh` writes, the GC chains as its
        skeleton (joined by `parents`, GC name -> parent name; None: inferred), no clip."""
        from ngc_gen.export import ExportSettings, export_shape

        version, shape = self.snapshot()
        settings = ExportSettings.from_yaml(resolution=int(resolution))
        summary, _, _ = export_shape(shape, Path(path), settings, parents,
                                     mesh=self.mesh(resolution, shape, version).mesh)
        self.message = (f"exported {summary['joints']} joints, {summary['vertices']} vertices "
                        f"to {path}")
        return Outcome(True, self.message, (Path(path),))


def describe(op: dict) -> str:
    """A short label of an op for messages: `scale arm t=0.5 factor=1.2`."""
    parts = [op["op"], str(op.get("gc"))]
    for k in ("indices", "t", "t0", "t1", "factor", "degrees", "blend"):
        if k in op:
            v = op[k]
            parts.append(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}")
    if "rotate" in op:
        parts.append(f"degrees={op['rotate']['degrees']:.4g}")
    if "source" in op:
        parts.append(f"from {op['source']['shape']}/{op['source']['gc']}")
    return " ".join(parts)
