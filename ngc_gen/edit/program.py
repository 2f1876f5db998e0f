"""Edit programs: a YAML list of ops applied to one fitted shape's GCs (docs/editing.md).

```yaml
name: bent_tail                 # used for the output folder
description: ...                # optional
shape: creature_0003            # the shape to edit (edit.py's shape= overrides it)
smooth_union: 0.0               # optional: smooth-union width where GCs overlap (0: hard min)
ops:
  - {op: bend, gc: tail, indices: [2, 3], offsets: [[0, 0, 0.1], [0, 0, 0.2]]}
```

Ops (`gc` names one GC; where marked, a list of names or `all`):
- bend / move: indices, offsets                    (control points; keys follow the curve)
- stretch: t0, t1, factor [, samples]               (the network's t-range gets longer)
- scale: t (a key t, or null: every key), factor [, falloff]      (list allowed)
- twist: t (or null), degrees [, falloff]; twist_ramp: t0, t1, degrees   (list allowed)
- rigid: R, t; rotate: axis, degrees [, pivot]; translate: offset  (list allowed; all GCs of
  the list move together, rotate's pivot defaults to the first GC's start)
- handles: gc, [at: [t_a, t_b]], [rotate: {axis, degrees, pivot}], [translate], [fixed: GC
  names], [attached: {gc: [names]}], [on_unreachable]: drag the handle points of `gc` over
  t in `at` (default [0.9, 1]) by the rigid motion; `ngc_gen.edit.handles` bends the GCs.
- mix: gc (or list), source: {shape, gc, ckpt}, [blend: replace | constant | linear |
  truncated_linear | smoothstep, with w / t0, t1], [geometry: source | target]
  (source, the default: the source part's GCs attached at this shape's joint, and its
  features; target: this shape's GCs, features blended inside them).
The shape-changing single-GC ops (bend, move, stretch, scale, twist, twist_ramp) take
`carry: [names]`: those GCs follow the edit rigidly at their attachment point (a head on a
bent neck, front legs on a stretched torso). A point (`pivot`) is [x, y, z] or {gc, t}: the
curve point of that GC at the network's t (after the previous ops).

`EditProgram.from_dict` checks the structure (op names, fields); `apply_program` runs the ops
on the GCs, which also checks every value (GC names, t ranges, factors) through the ops
themselves. Both raise EditError naming the program, the op index, the GC and the field, and
neither writes anything: an entry point validates the whole program before any output.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import torch
from scipy.spatial.transform import Rotation

from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.shape import PartFeatures
from ngc_gen.shape.mixing import mixed_parts

from .blend import mix_weight
from .body import resolve_body_directions
from .crossings import crossings
from .errors import EditError, in_program
from .handles import deform_by_handles
from .ops import OPS, check_array, check_number, check_t, curve_points_at, local_motion
from .spec import OPS as OPS_SPEC
from .spec import _gc_label, check_program, op_fields  # noqa: F401  (op_fields re-exported)

MULTI_OPS = {op for op, spec in OPS_SPEC.items() if spec.fields["gc"].type == "gcs"}
CARRY_OPS = {op for op, spec in OPS_SPEC.items() if "carry" in spec.fields}
ALL_OPS = sorted(OPS_SPEC)
SOURCE_FIELDS = {"shape", "gc", "ckpt"}


@dataclass
class EditProgram:
    """A validated program: name, ops (plain dicts with an `op` key) and where it came from."""

    name: str
    ops: list[dict]
    shape: str | None = None
    smooth_union: float = 0.0
    description: str = ""
    source: str | None = None

    def apply_to(self, shape, resolve: "SourceResolver | None" = None):
        """The `ngc_gen.shape.Shape` after this program: edited GCs, mixed parts, the program's
        smooth-union width (a shape with the blended union keeps it: it has no seam to
        smooth); the per-op records go to `info["edit_log"]`. `Shape.edited` calls
        this (the shape layer does not import edits)."""
        result = apply_program(self, shape.gcs, resolve, frame=shape.info.get("frame"))
        index = {n: j for j, n in enumerate(shape.gc_names)}
        mixes = {**shape.mixes, **{index[n]: f for n, f in result.mixes.items()}}
        return shape.replaced(gcs=result.gcs, mixes=mixes,
                              smooth=0.0 if shape.blend else self.smooth_union,
                              info={**shape.info, "edit_log": result.log,
                                    "program": self.name,
                                    "crossings": crossings(shape.gcs, result.gcs)})

    @classmethod
    def from_dict(cls, d, source: str | None = None) -> "EditProgram":
        """Check the program's structure against the op reference (`spec.check_program`: known
        top-level keys, a non-empty list of ops, every op known, its required fields present,
        no unknown field, every field of its type)."""
        p = check_program(d, source)
        return cls(p["name"], p["ops"], p["shape"], p["smooth_union"], p["description"], source)


# ---- sources for part mixing -----------------------------------------------------------------
@dataclass
class MixSource:
    """What a mix reads from a source part: its code (code_dim,) and its GC."""

    code: torch.Tensor
    gc: GeneralizedCylinder
    label: str


#: resolve(shape or None, gc name, ckpt path or None) -> MixSource; raises EditError
SourceResolver = Callable[[str | None, str, str | None], MixSource]


@dataclass
class ProgramResult:
    """The edited GCs (input order), the planned mixes by GC name, and per-op records."""

    gcs: list[GeneralizedCylinder]
    mixes: dict[str, PartFeatures] = field(default_factory=dict)
    log: list[dict] = field(default_factory=list)


# ---- applying --------------------------------------------------------------------------------
def _names(entry: dict, gcs: dict, op: str, multi: bool) -> list[str]:
    g = entry.get("gc")
    if multi and g == "all":
        return list(gcs)
    names = g if (multi and isinstance(g, list)) else [g]
    if not names or not all(isinstance(n, str) for n in names):
        want = "a GC name, a list of names or 'all'" if multi else "one GC name"
        raise EditError(f"must be {want}", op=op, field="gc", value=g)
    for n in names:
        if n not in gcs:
            raise EditError(f"unknown GC; this shape's GCs are {list(gcs)}", op=op, gc=n,
                            field="gc", value=n, fix="use one of the shape's GC names")
    if len(set(names)) != len(names):
        raise EditError("lists a GC twice", op=op, field="gc", value=g)
    return names


def resolve_point(ref, gcs: dict, op: str, field_name: str) -> np.ndarray:
    """[x, y, z], or {gc, t}: the curve point of that GC at the network's t."""
    if isinstance(ref, dict):
        if set(ref) != {"gc", "t"}:
            raise EditError("a point is [x, y, z] or {gc: name, t: 0..1}", op=op,
                            field=field_name, value=ref)
        name = ref["gc"]
        if name not in gcs:
            raise EditError(f"unknown GC; this shape's GCs are {list(gcs)}", op=op, gc=name,
                            field=f"{field_name}.gc", value=name)
        g = gcs[name]
        t = check_t(op, g, f"{field_name}.t", ref["t"])
        return g.to_world(np.array([[2.0 * t - 1.0, 0.0, 0.0]]))[0]
    return check_array(op, None, field_name, ref, (3,))


def _motion(spec, gcs: dict, op: str, default_pivot: np.ndarray, prefix: str = ""):
    """(R, pivot) of a {axis, degrees, pivot} rotation spec (None -> identity)."""
    if spec is None:
        return np.eye(3), default_pivot
    if not isinstance(spec, dict) or not {"axis", "degrees"} <= set(spec) \
            or set(spec) - {"axis", "degrees", "pivot"}:
        raise EditError("must be {axis: [x, y, z], degrees: number, pivot: point (optional)}",
                        op=op, field=prefix + "rotate", value=spec)
    axis = check_array(op, None, prefix + "rotate.axis", spec["axis"], (3,))
    if np.linalg.norm(axis) < 1e-12:
        raise EditError("must be a nonzero vector", op=op, field=prefix + "rotate.axis",
                        value=spec["axis"])
    deg = check_number(op, None, prefix + "rotate.degrees", spec["degrees"])
    pivot = default_pivot if spec.get("pivot") is None else \
        resolve_point(spec["pivot"], gcs, op, prefix + "rotate.pivot")
    R = Rotation.from_rotvec(axis / np.linalg.norm(axis) * math.radians(deg)).as_matrix()
    return R, pivot


def handle_points(gc: GeneralizedCylinder, at=(0.9, 1.0), n_t: int = 5, n_ring: int = 8,
                  ring: float = 0.5) -> np.ndarray:
    """Handle points (n_t (n_ring + 1), 3) of a GC region: curve points and rings of relative
    radius `ring` at n_t network parameters t in [at[0], at[1]]."""
    t = np.linspace(at[0], at[1], n_t)
    ang = np.linspace(0.0, 2 * np.pi, n_ring, endpoint=False)
    a = np.concatenate([[0.0], ring * np.cos(ang)])
    b = np.concatenate([[0.0], ring * np.sin(ang)])
    u = np.repeat(2.0 * t - 1.0, len(a))
    rel = np.stack([u, np.tile(a, n_t), np.tile(b, n_t)], 1)
    return gc.to_world(rel)


def region_mask(gc: GeneralizedCylinder, points, at) -> np.ndarray:
    """(N,) bool: points inside `gc` whose network t lies in `at` = [t_a, t_b]; an interval
    reaching t = 0 or 1 includes that end's cap."""
    rel = gc.to_relative(np.asarray(points, dtype=np.float64))
    u = rel[:, 0]
    lo = -np.inf if at[0] <= 0.0 else 2.0 * at[0] - 1.0
    hi = np.inf if at[1] >= 1.0 else 2.0 * at[1] - 1.0
    return GeneralizedCylinder.inside_relative(rel) & (u >= lo) & (u <= hi)


def _at(entry, gc, op) -> tuple[float, float]:
    at = entry.get("at", [0.9, 1.0])
    if not isinstance(at, (list, tuple)) or len(at) != 2:
        raise EditError("must be [t_a, t_b]", op=op, gc=gc.name, field="at", value=at)
    a, b = check_t(op, gc, "at[0]", at[0]), check_t(op, gc, "at[1]", at[1])
    if not a <= b:
        raise EditError("needs t_a <= t_b", op=op, gc=gc.name, field="at", value=at)
    return a, b


def _carry(entry, name: str, old, new, gcs: dict, op: str) -> None:
    """Move the GCs listed in `carry` by the edit's local motion at their attachment end."""
    carry = entry.get("carry") or []
    if isinstance(carry, str):
        carry = [carry]
    if not isinstance(carry, list):
        raise EditError("must be a list of GC names", op=op, gc=name, field="carry", value=carry)
    for c in carry:
        if c not in gcs or c == name:
            raise EditError(f"must name other GCs of this shape ({[g for g in gcs if g != name]})",
                            op=op, gc=name, field="carry", value=c)
        g = gcs[c]
        ends = curve_points_at(g, [0.0, 1.0])
        rel = old.to_relative(ends)
        measure = GeneralizedCylinder.relative_measure(np.asarray(rel))
        R, t = local_motion(old, new, ends[int(np.argmin(measure))])
        gcs[c] = g.transformed(R, t)


def _gc_op(entry: dict, gcs: dict, op: str) -> dict:
    names = _names(entry, gcs, op, op in MULTI_OPS)
    if entry.get("carry") and len(names) != 1:
        raise EditError("carry needs a single edited GC", op=op, field="carry")
    params = {k: v for k, v in entry.items() if k not in ("op", "gc", "carry")}
    if op == "rotate":
        pivot = params.get("pivot")
        params["pivot"] = (curve_points_at(gcs[names[0]], [0.0])[0] if pivot is None
                           else resolve_point(pivot, gcs, op, "pivot"))
    for n in names:
        old = gcs[n]
        gcs[n] = OPS[op](old, **params)
        if op in CARRY_OPS:
            _carry(entry, n, old, gcs[n], gcs, op)
    out = {"op": op, "gcs": names}
    if op in CARRY_OPS and entry.get("carry"):
        out["carried"] = list(entry["carry"]) if isinstance(entry["carry"], list) \
            else [entry["carry"]]
    return out


def _handles_op(entry: dict, gcs: dict) -> dict:
    op = "handles"
    (name,) = _names(entry, gcs, op, False)
    gc = gcs[name]
    at = _at(entry, gc, op)
    H = handle_points(gc, at)
    fixed = entry.get("fixed")
    far_end = 0.0 if (at[0] + at[1]) >= 1.0 else 1.0
    if fixed is None:
        F = curve_points_at(gc, [far_end])
        fixed_names = []
    else:
        fixed_names = [fixed] if isinstance(fixed, str) else fixed
        if not isinstance(fixed_names, list) or not fixed_names:
            raise EditError("must be a list of GC names (the region that stays)", op=op,
                            gc=name, field="fixed", value=fixed)
        for f in fixed_names:
            if f not in gcs:
                raise EditError(f"unknown GC; this shape's GCs are {list(gcs)}", op=op, gc=f,
                                field="fixed", value=f)
        F = np.concatenate([curve_points_at(gcs[f], np.linspace(0, 1, 33)) for f in fixed_names])
    pivot0 = curve_points_at(gc, [far_end])[0]
    R, pivot = _motion(entry.get("rotate"), gcs, op, pivot0)
    move = check_array(op, gc, "translate", entry.get("translate", [0.0, 0.0, 0.0]), (3,))
    T = (H - pivot) @ R.T + pivot + move
    attached = entry.get("attached")
    if attached is not None and not (isinstance(attached, dict) and all(
            isinstance(v, list) for v in attached.values())):
        raise EditError("must map a bent GC to a list of GCs that follow it", op=op, gc=name,
                        field="attached", value=attached)
    names = list(gcs)
    out, info = deform_by_handles([gcs[n] for n in names], H, T, F, attached=attached,
                                  on_unreachable=entry.get("on_unreachable", "raise"),
                                  return_info=True)
    gcs.update(zip(names, out))
    return {"op": op, "gcs": sorted(info.bent), "followers": sorted(info.followers),
            "fixed": fixed_names, "residual": info.residual,
            "lengths": {k: [v["length_old"], v["length_new"]] for k, v in info.bent.items()}}


def _mix_weight(entry: dict, op: str = "mix"):
    return mix_weight(entry.get("blend", "replace"), op=op,
                      **{k: entry[k] for k in ("t0", "t1", "w") if k in entry})


def _mix_op(entry: dict, gcs: dict, resolve: SourceResolver | None, mixes: dict) -> dict:
    op = "mix"
    names = _names(entry, gcs, op, True)
    src = entry["source"]
    if isinstance(src, str):
        src = {"shape": src}
    if not isinstance(src, dict) or set(src) - SOURCE_FIELDS:
        raise EditError(f"must be a shape name or a mapping with keys from "
                        f"{sorted(SOURCE_FIELDS)}", op=op, gc=_gc_label(names), field="source",
                        value=entry["source"])
    src_gcs = src.get("gc", names)
    src_gcs = [src_gcs] if isinstance(src_gcs, str) else src_gcs
    if not isinstance(src_gcs, list) or len(src_gcs) != len(names):
        raise EditError(f"must name one source GC per target GC ({len(names)})", op=op,
                        gc=_gc_label(names), field="source.gc", value=src.get("gc"))
    weight = _mix_weight(entry)
    geometry = entry.get("geometry", "source")
    if geometry not in ("target", "source"):
        raise EditError("must be 'target' (keep this shape's GCs) or 'source' (use the "
                        "source's GCs, moved onto this shape)", op=op, gc=_gc_label(names),
                        field="geometry", value=geometry)
    if resolve is None:
        raise EditError("part mixing needs a checkpoint to read source codes from", op=op)
    sources = []
    for n, s in zip(names, src_gcs):
        try:
            sources.append(resolve(src.get("shape"), s, src.get("ckpt")))
        except EditError as e:
            raise EditError(e.what, op=op, gc=n, field=e.field or "source", value=e.value,
                            fix=e.fix) from None
    for n in names:
        if n in mixes:
            raise EditError("this GC is already mixed by an earlier op", op=op, gc=n,
                            fix="mix each GC once (one source and one blend per GC)")
    parts = mixed_parts([gcs[n] for n in names], [s.gc for s in sources],
                        [s.code for s in sources], weight, geometry, [s.label for s in sources])
    for n, (gc, feats) in zip(names, parts):
        gcs[n], mixes[n] = gc, feats
    return {"op": op, "gcs": names, "sources": [s.label for s in sources],
            "blend": repr(weight), "geometry": geometry}


def apply_program(program: EditProgram, gcs: list[GeneralizedCylinder],
                  resolve: SourceResolver | None = None,
                  frame: dict | None = None) -> ProgramResult:
    """Run the program's ops in order on `gcs` (never changed; GCs are immutable).

    resolve(shape, gc, ckpt) -> MixSource reads source parts for `mix` (None: mixing is an
    error). frame: the shape's body frame {up, front}, which body directions (`axis: forward`)
    resolve through (`body.resolve_body_directions`). Any problem raises EditError with the
    program and op index."""
    state = {g.name: g for g in gcs}
    mixes: dict[str, PartFeatures] = {}
    log = []
    for i, entry in enumerate(resolve_body_directions(program.ops, frame, program.source)):
        op = entry["op"]
        try:
            if op == "handles":
                rec = _handles_op(entry, state)
            elif op == "mix":
                rec = _mix_op(entry, state, resolve, mixes)
            else:
                rec = _gc_op(entry, state, op)
        except EditError as e:  # named as the program names the op (bend, not move_points)
            raise in_program(e, program.source, i, op=op) from None
        except (TypeError, ValueError) as e:  # a value no op check anticipated
            raise EditError(f"bad value ({type(e).__name__}: {e})", op=op,
                            gc=_gc_label(entry.get("gc")), program=program.source,
                            index=i) from None
        log.append(rec)
    return ProgramResult([state[g.name] for g in gcs], mixes, log)
