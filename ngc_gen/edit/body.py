"""Edit programs in the body frame: an axis or offset written as a body direction (`forward`,
`up`, `left`, `-forward`, ...; `spec.BODY_DIRECTIONS`) resolves through the shape's frame, the
`frame` its annotation records (`ngc_gen.data.body_frame`), so one program swings a front leg
forward on any collection whatever way its meshes face. An axis given as [x, y, z] is used as
it is."""
from __future__ import annotations

import numpy as np

from ngc_gen.data.body_frame import body_axes, read_frame

from .errors import EditError
from .spec import body_direction

# (op, field path) of every field that takes a body direction (spec's `axis` and `offset`)
BODY_FIELDS = (("rotate", ("axis",)), ("translate", ("offset",)),
               ("handles", ("rotate", "axis")), ("handles", ("translate",)))


def _resolve(value, axes, where: dict):
    """[x, y, z] for a body direction or a {direction: length} mapping; value as it is else."""
    if axes is None:
        raise EditError(f"{value!r} names a body direction, but the shape records no body frame "
                        f"(its annotation has no `frame`)", **where,
                        fix="write the direction as [x, y, z], or edit a shape of a collection "
                            "annotated with a template (stage=annotate annotate.template=T), "
                            "whose frame is recorded")

    def one(name):
        d, sign = body_direction(name)
        return sign * axes[d]

    if isinstance(value, str):
        return one(value).tolist()
    return sum((float(v) * one(k) for k, v in value.items()), np.zeros(3)).tolist()


def _uses_body(value) -> bool:
    return body_direction(value) is not None or (
        isinstance(value, dict) and any(body_direction(k) is not None for k in value))


def resolve_body_directions(ops: list[dict], frame: dict | None,
                            source: str | None = None) -> list[dict]:
    """`ops` with every body direction replaced by its [x, y, z] in `frame` ({up, front}; None:
    the shape has none, and a body direction is an EditError naming the op and field)."""
    axes = None if frame is None else body_axes(read_frame(
        {k: frame[k] for k in ("up", "front")}))
    out = []
    for i, entry in enumerate(ops):
        entry = dict(entry)
        for op, path in BODY_FIELDS:
            if entry.get("op") != op:
                continue
            holder = entry
            for key in path[:-1]:
                if not isinstance(holder.get(key), dict):
                    holder = None
                    break
                holder[key] = dict(holder[key])
                holder = holder[key]
            if holder is None or not _uses_body(holder.get(path[-1])):
                continue
            where = dict(program=source, index=i, op=op, field=".".join(path),
                         value=holder[path[-1]])
            holder[path[-1]] = _resolve(holder[path[-1]], axes, where)
        out.append(entry)
    return out
