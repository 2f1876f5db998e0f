"""The one error type of the edit layer."""
from __future__ import annotations


def _show(value) -> str:
    """A short, plain rendering of a bad value (numpy scalars and arrays as Python values)."""
    if not type(value).__module__.startswith("numpy"):
        return repr(value)
    import numpy as np  # here, not at import: edit.py checks programs before numpy loads

    if isinstance(value, np.ndarray):
        value = np.round(value.astype(np.float64), 6).tolist() if value.dtype.kind == "f" \
            else value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    return repr(value)


class EditError(ValueError):
    """An edit that cannot be applied: names the op, the GC, the bad field/value and a fix.

        EditError("must lie in [0, 1]", op="stretch", gc="body", field="t0", value=1.3,
                  fix="give t as normalised arc length")
        -> "edit 'stretch' on GC 'body': t0 = 1.3: must lie in [0, 1]. Fix: give t as ..."

    Subclasses ValueError so callers that only know the standard library can catch it; the
    parts stay available as attributes for tools that point at the offending program entry.
    An edit program adds where the op came from (`in_program`):
    "program conf/edit/x.yaml, ops[2]: edit 'twist' on GC 'tail': ..."
    """

    def __init__(self, what: str, *, op: str | None = None, gc: str | None = None,
                 field: str | None = None, value=None, fix: str | None = None,
                 program: str | None = None, index: int | None = None):
        self.what, self.op, self.gc, self.field, self.value, self.fix = (
            what, op, gc, field, value, fix)
        self.program, self.index = program, index
        where = []
        if program is not None or index is not None:
            where.append(", ".join(([f"program {program}"] if program is not None else [])
                                   + ([f"ops[{index}]"] if index is not None else [])))
        if op is not None:
            where.append(f"edit '{op}'" + (f" on GC '{gc}'" if gc is not None else ""))
        elif gc is not None:
            where.append(f"GC '{gc}'")
        if field is not None:
            where.append(f"{field} = {_show(value)}" if value is not None else f"field '{field}'")
        message = ": ".join(where + [what])
        if fix:
            message = f"{message.rstrip('.')}. Fix: {fix}"
        super().__init__(message)


def in_program(e: EditError, program: str | None, index: int | None,
               op: str | None = None) -> EditError:
    """The same error, located in an edit program file and its op index; `op` renames the op
    as the program calls it (`bend`, where the function raising was `move_points`)."""
    return EditError(e.what, op=op or e.op, gc=e.gc, field=e.field, value=e.value, fix=e.fix,
                     program=program if program is not None else e.program,
                     index=index if index is not None else e.index)
