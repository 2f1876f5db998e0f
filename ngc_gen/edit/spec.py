"""The edit-op reference: every op of an edit program, its fields with their types, and a
one-line example. The one source of op fields: `EditProgram.from_dict` checks programs against
it, edit.py prints it when a program names an unknown op or field, and the table of
docs/edit_ops.md is generated from it (tests/edit/test_spec.py keeps them equal).

Torch-free (only the standard library, `ngc_gen.values` and EditError), so edit.py rejects a
malformed program in about a second, before torch loads. Numbers follow the project's one rule
(`ngc_gen.values`): a quoted number (`degrees: "30"`) is text and is refused, as in configs and
annotations, so a program is written back with the types it was read with. These checks are about structure and types (a number where
a number goes, a list of GC names where names go); values that depend on the shape (GC names,
t ranges, factors) are checked by the ops when the program runs.
"""
from __future__ import annotations

from dataclasses import dataclass

from ngc_gen.values import NumberError, is_number, looks_like_number, read_number

from .errors import EditError

PROGRAM_KEYS = ("name", "description", "shape", "smooth_union", "ops")
# directions in the shape's body frame (its annotation's `frame`: up, front; left = up x front),
# usable wherever an op takes an axis or an offset; `-name` is the opposite direction
BODY_DIRECTIONS = ("forward", "up", "left")
# the blends of blend.BLEND_PARAMS (tests/edit/test_spec.py keeps them equal)
BLEND_NAMES = ("replace", "constant", "linear", "truncated_linear", "smoothstep")


# ---- field types: (what a user reads, a check) -------------------------------------------------
def _number(x) -> bool:
    return is_number(x)


def _quoted_number(x) -> str | None:
    """The first quoted number (text that reads as a number) inside a value, or None."""
    if isinstance(x, str):
        return x if looks_like_number(x) else None
    items = x.values() if isinstance(x, dict) else x if isinstance(x, (list, tuple)) else ()
    for v in items:
        q = _quoted_number(v)
        if q is not None:
            return q
    return None


def _vector(x, n: int = 3) -> bool:
    return isinstance(x, (list, tuple)) and len(x) == n and all(_number(v) for v in x)


def _name(x) -> bool:
    return isinstance(x, str) and x != ""


def _names(x) -> bool:
    return _name(x) or (isinstance(x, list) and len(x) > 0 and all(_name(v) for v in x))


def body_direction(x) -> tuple[str, float] | None:
    """(name, sign) of a body direction ('forward', '-up', ...), or None if x is not one."""
    if not isinstance(x, str):
        return None
    name = x.strip()
    sign = -1.0 if name.startswith("-") else 1.0
    name = name.lstrip("+-")
    return (name, sign) if name in BODY_DIRECTIONS and len(x.strip()) - len(name) <= 1 else None


def _axis(x) -> bool:
    return _vector(x) or body_direction(x) is not None


def _offset(x) -> bool:
    """[x, y, z], or a mapping of body directions to lengths ({forward: 0.1, up: 0.05})."""
    return _vector(x) or (isinstance(x, dict) and len(x) > 0 and all(
        body_direction(k) is not None and _number(v) for k, v in x.items()))


def _point(x) -> bool:
    return _vector(x) or (isinstance(x, dict) and set(x) == {"gc", "t"} and _name(x["gc"])
                          and _number(x["t"]))


def _rotation(x) -> bool:
    return (isinstance(x, dict) and {"axis", "degrees"} <= set(x)
            and set(x) <= {"axis", "degrees", "pivot"} and _axis(x["axis"])
            and _number(x["degrees"]) and (x.get("pivot") is None or _point(x["pivot"])))


def _source(x) -> bool:
    return _name(x) or (isinstance(x, dict) and len(x) > 0 and set(x) <= {"shape", "gc", "ckpt"}
                        and all(v is None or _names(v) for v in x.values()))


@dataclass(frozen=True)
class FieldType:
    text: str                      # what the reference says
    check: object                  # value -> bool
    choices: tuple[str, ...] = ()  # for a choice: the allowed values

    def ok(self, value) -> bool:
        return value in self.choices if self.choices else bool(self.check(value))


def _choice(*values: str) -> FieldType:
    return FieldType(" | ".join(values), None, values)


TYPES = {
    "gc": FieldType("a GC name", _name),
    "gcs": FieldType("a GC name, a list of names, or all", _names),
    "names": FieldType("a list of GC names", _names),
    "t": FieldType("a number in [0, 1]", _number),
    "t_or_null": FieldType("a number in [0, 1], or null (every key)",
                           lambda x: x is None or _number(x)),
    "number": FieldType("a number", _number),
    "width": FieldType("a number > 0, or null", lambda x: x is None or _number(x)),
    "count": FieldType("an integer", lambda x: isinstance(x, int) and not isinstance(x, bool)),
    "factor": FieldType("a number > 0, or [f_y, f_z]", lambda x: _number(x) or _vector(x, 2)),
    "indices": FieldType("an int or a list of ints",
                         lambda x: (isinstance(x, int) and not isinstance(x, bool)) or (
                             isinstance(x, list) and len(x) > 0
                             and all(isinstance(v, int) and not isinstance(v, bool) for v in x))),
    "offsets": FieldType("[x, y, z], or one [x, y, z] per index",
                         lambda x: _vector(x) or (isinstance(x, list) and len(x) > 0
                                                  and all(_vector(v) for v in x))),
    "vec3": FieldType("[x, y, z]", _vector),
    "axis": FieldType("[x, y, z], or a body direction: forward, up, left, -forward, -up, -left "
                      "(the shape's frame)", _axis),
    "offset": FieldType("[x, y, z], or lengths along body directions: {forward: 0.1, up: 0.05}",
                        _offset),
    "matrix": FieldType("a 3x3 rotation, rows [[..], [..], [..]]",
                        lambda x: isinstance(x, list) and len(x) == 3
                        and all(_vector(r) for r in x)),
    "point": FieldType("[x, y, z], or {gc: name, t: 0..1} (a curve point)", _point),
    "range": FieldType("[t_a, t_b] in [0, 1]", lambda x: _vector(x, 2)),
    "rotation": FieldType("{axis: [x, y, z] or a body direction (-left: a leg swings forward), "
                          "degrees: number, pivot: point (optional)}", _rotation),
    "attached": FieldType("{bent GC: [names of GCs that follow it]}",
                          lambda x: isinstance(x, dict) and all(
                              _name(k) and isinstance(v, list) and all(_name(n) for n in v)
                              for k, v in x.items())),
    "source": FieldType("a shape name, or {shape, gc, ckpt}", _source),
    "blend": _choice(*BLEND_NAMES),
    "geometry": _choice("source", "target"),
    "on_unreachable": _choice("raise", "closest"),
}


@dataclass(frozen=True)
class Field:
    type: str
    required: bool = False
    fix: str = ""  # a hint beyond the type (shown when the value has the wrong form)


@dataclass(frozen=True)
class OpSpec:
    summary: str
    fields: dict[str, Field]
    example: str          # one line of YAML, as the op appears in `ops:`


def _f(type_: str, required: bool = False, fix: str = "") -> Field:
    return Field(type_, required, fix)


CARRY = _f("names", fix="the GCs that follow the edit rigidly, e.g. carry: [head]")

OPS: dict[str, OpSpec] = {
    "bend": OpSpec("move curve control points; keys follow the curve",
                   {"gc": _f("gc", True), "indices": _f("indices", True),
                    "offsets": _f("offsets", True), "carry": CARRY},
                   "{op: bend, gc: tail, indices: [2, 3], offsets: [[0, 0, 0.1], [0, 0, 0.2]]}"),
    "move": OpSpec("the same as bend",
                   {"gc": _f("gc", True), "indices": _f("indices", True),
                    "offsets": _f("offsets", True), "carry": CARRY},
                   "{op: move, gc: tail, indices: -1, offsets: [0, 0.1, 0]}"),
    "stretch": OpSpec("make the piece over [t0, t1] factor times longer",
                      {"gc": _f("gc", True), "t0": _f("t", True), "t1": _f("t", True),
                       "factor": _f("number", True), "samples": _f("count"), "carry": CARRY},
                      "{op: stretch, gc: torso, t0: 0.35, t1: 0.65, factor: 1.5, carry: [neck]}"),
    "scale": OpSpec("scale the radii at the key at t (null: every key)",
                    {"gc": _f("gcs", True), "t": _f("t_or_null", True),
                     "factor": _f("factor", True), "falloff": _f("width"), "carry": CARRY},
                    "{op: scale, gc: head, t: null, factor: 1.35, carry: [ear_l, ear_r]}"),
    "twist": OpSpec("add twist (degrees) at the key at t (null: every key)",
                    {"gc": _f("gcs", True), "t": _f("t_or_null", True),
                     "degrees": _f("number", True), "falloff": _f("width"), "carry": CARRY},
                    "{op: twist, gc: tail, t: 1.0, degrees: 90}"),
    "twist_ramp": OpSpec("twist growing from 0 at t0 to degrees at t1",
                         {"gc": _f("gcs", True), "t0": _f("t", True), "t1": _f("t", True),
                          "degrees": _f("number", True), "carry": CARRY},
                         "{op: twist_ramp, gc: leg_fl, t0: 0.1, t1: 1.0, degrees: 150}"),
    "rigid": OpSpec("rigid motion x -> R x + t of the GCs",
                    {"gc": _f("gcs", True), "R": _f("matrix", True), "t": _f("vec3", True)},
                    "{op: rigid, gc: head, R: [[1, 0, 0], [0, 1, 0], [0, 0, 1]], t: [0, 0, 0.1]}"),
    "rotate": OpSpec("rotate the GCs about an axis through pivot (default: the first GC's start)",
                     {"gc": _f("gcs", True), "axis": _f("axis", True),
                      "degrees": _f("number", True), "pivot": _f("point")},
                     "{op: rotate, gc: [head, ear_l, ear_r], axis: [0, 1, 0], degrees: 20}"),
    "translate": OpSpec("move the GCs by offset",
                        {"gc": _f("gcs", True), "offset": _f("offset", True)},
                        "{op: translate, gc: all, offset: [-0.06, 0, 0]}"),
    "handles": OpSpec("drag the handle points of gc over t in `at` by a rigid motion; the GCs "
                      "between them and the fixed region bend (arc length kept)",
                      {"gc": _f("gc", True), "at": _f("range"), "rotate": _f("rotation"),
                       "translate": _f("offset"),
                       "fixed": _f("names", fix="whole GCs stay, e.g. fixed: [thorax]; to hold "
                                                "part of the dragged GC, move `at` instead"),
                       "attached": _f("attached"), "on_unreachable": _f("on_unreachable")},
                      "{op: handles, gc: leg_l1, at: [0.85, 1.0], fixed: [thorax], "
                      "rotate: {axis: [0, 0, 1], degrees: 45, pivot: {gc: leg_l1, t: 0}}}"),
    "mix": OpSpec("take another shape's part: its GC at this joint (geometry: source) and its "
                  "features, blended along t",
                  {"gc": _f("gcs", True), "source": _f("source", True), "blend": _f("blend"),
                   "t0": _f("t"), "t1": _f("t"), "w": _f("number"), "geometry": _f("geometry")},
                  "{op: mix, gc: neck, source: {shape: creature_0002}, "
                  "blend: truncated_linear, t0: 0.5, t1: 1.0}"),
}


def op_fields(op: str) -> dict[str, bool]:
    """Every field an op takes (besides `op`), with whether it is required."""
    return {name: f.required for name, f in OPS[op].fields.items()}


# ---- the reference, as edit.py prints it and as docs/edit_ops.md shows it ---------------------
def _field_text(name: str, f: Field) -> str:
    return f"{name}{'*' if f.required else ''}: {TYPES[f.type].text}"


def reference(ops: list[str] | None = None) -> str:
    """The reference of `ops` (default: every op) as plain text."""
    lines = ["edit ops (* = required field):"]
    for op in ops or list(OPS):
        spec = OPS[op]
        lines.append(f"  {op}: {spec.summary}")
        lines.append("      " + "; ".join(_field_text(n, f) for n, f in spec.fields.items()))
        lines.append(f"      e.g. - {spec.example}")
    return "\n".join(lines)


def reference_markdown() -> str:
    """docs/edit_ops.md's edit-op table (generated; do not edit that copy by hand)."""
    def cell(text: str) -> str:
        return text.replace("|", "\\|")

    rows = ["| op | what it does | fields | example |", "|---|---|---|---|"]
    for op, spec in OPS.items():
        fields = "<br>".join(f"`{n}`{' (required)' if f.required else ''}: "
                             f"{cell(TYPES[f.type].text)}" for n, f in spec.fields.items())
        rows.append(f"| `{op}` | {cell(spec.summary)} | {fields} | `{spec.example}` |")
    return "\n".join(rows)


# ---- checking a program's structure ------------------------------------------------------------
def _gc_label(gc) -> str | None:
    if gc is None:
        return None
    if isinstance(gc, list):
        return ", ".join(map(str, gc))
    return str(gc)


def _error(what: str, source, index=None, *, op=None, help_ops=(), **kw) -> EditError:
    """EditError located in the program; `help_ops` (None: every op) attaches their reference
    as `.help`, which edit.py prints below the one-line error."""
    e = EditError(what, program=source, index=index, op=op, **kw)
    if help_ops != ():
        e.help = reference(help_ops)
    return e


def check_op(entry, index: int, source: str | None) -> dict:
    """One op entry, checked: a mapping with a known `op`, its required fields, no unknown
    field, each field of its type. Returns a copy."""
    if not isinstance(entry, dict) or "op" not in entry:
        raise _error(f"each op must be a mapping with an 'op' name, got {entry!r}", source, index,
                     fix="write ops like `- {op: twist, gc: tail, t: 1.0, degrees: 90}`")
    name = entry["op"]
    if not isinstance(name, str) or name not in OPS:
        raise _error(f"unknown op; use one of {sorted(OPS)}", source, index, field="op",
                     value=name, help_ops=None)
    spec, gc = OPS[name], _gc_label(entry.get("gc"))
    extra = sorted(set(entry) - {"op"} - set(spec.fields))
    if extra:
        raise _error(f"unknown field(s) {extra}; '{name}' takes {sorted(spec.fields)}", source,
                     index, op=name, gc=gc, help_ops=[name])
    missing = [f for f, fs in spec.fields.items() if fs.required and f not in entry]
    if missing:
        raise _error(f"missing required field(s) {missing}; '{name}' takes "
                     f"{sorted(spec.fields)}", source, index, op=name, gc=gc, help_ops=[name])
    for field_name, value in entry.items():
        if field_name == "op":
            continue
        f = spec.fields[field_name]
        if value is None and not f.required:
            continue  # an optional field left at its default
        ftype = TYPES[f.type]
        if not ftype.ok(value):
            quoted = None if ftype.choices else _quoted_number(value)
            if quoted is not None:  # the one message for a quoted number (ngc_gen.values)
                raise _error(f"{quoted!r} is quoted text, not a number", source, index, op=name,
                             gc=gc, field=field_name, value=value,
                             fix=f"write {quoted.strip()} without quotes", help_ops=[name])
            what = (f"unknown {field_name}; use one of {list(ftype.choices)}" if ftype.choices
                    else f"must be {ftype.text}")
            raise _error(what, source, index, op=name, gc=gc, field=field_name, value=value,
                         fix=f.fix or f"see the example: - {spec.example}", help_ops=[name])
    return dict(entry)


def check_program(d, source: str | None = None) -> dict:
    """A program's structure, checked: known top-level keys, a non-empty list of ops, each op
    checked by `check_op`, `shape` a name and `smooth_union` a width >= 0. Returns the parts
    {name, ops, shape, smooth_union, description}; EditError naming the program and op."""
    if not isinstance(d, dict):
        raise _error(f"a program must be a mapping with 'ops', got {type(d).__name__}", source,
                     fix="write `name: ...` and `ops: [...]` at the top level")
    unknown = set(d) - set(PROGRAM_KEYS)
    if unknown:
        raise _error(f"unknown program keys {sorted(unknown)}; allowed {sorted(PROGRAM_KEYS)}",
                     source)
    ops = d.get("ops")
    if not isinstance(ops, list) or not ops:
        raise _error(f"'ops' must be a non-empty list of ops, got {ops!r}", source, field="ops",
                     fix="list ops like `- {op: twist, gc: tail, t: 1.0, degrees: 90}`")
    checked = [check_op(entry, i, source) for i, entry in enumerate(ops)]
    shape = d.get("shape")
    if shape is not None and not isinstance(shape, str):
        raise _error(f"shape must be a shape name, got {shape!r}", source, field="shape")
    k = d.get("smooth_union")
    try:
        k = 0.0 if k is None else read_number(k, minimum=0)
    except NumberError as e:
        raise _error(f"{e.what} (a width; 0: hard minimum over GCs)", source,
                     field="smooth_union", value=d.get("smooth_union"), fix=e.fix) from None
    return {"name": str(d.get("name", "program")), "ops": checked, "shape": shape,
            "smooth_union": k, "description": str(d.get("description", "") or "")}


if __name__ == "__main__":  # docs/edit_ops.md's table: python -m ngc_gen.edit.spec
    print(reference_markdown())
