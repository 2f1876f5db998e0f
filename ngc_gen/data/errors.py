"""The one error type of the data layer.

Every message answers three questions: what was wrong, where (file, GC name, field) and how to
fix it. ``DataError`` subclasses ``ValueError`` so callers that only know the standard library
can still catch it.
"""

from __future__ import annotations

import os


class DataError(ValueError):
    """Bad input data: a mesh, an annotation, or GCs that do not cover their mesh.

    Build it from parts so every message has the same shape::

        DataError("radius must be > 0", path="ant.yaml", gc="leg_1", field="keys[0].radii",
                  fix="give both radii positive values")
        -> "ant.yaml: GC 'leg_1': field 'keys[0].radii': radius must be > 0. Fix: give both ..."

    The parts stay available as attributes (``path``, ``gc``, ``field``, ``fix``) for tools
    that want to point at the offending entry.
    """

    def __init__(
        self,
        what: str,
        *,
        path: str | os.PathLike | None = None,
        gc: str | None = None,
        field: str | None = None,
        fix: str | None = None,
    ) -> None:
        self.what = what
        self.path = None if path is None else os.fspath(path)
        self.gc = gc
        self.field = field
        self.fix = fix
        where = []
        if self.path is not None:
            where.append(self.path)
        if gc is not None:
            where.append(f"GC '{gc}'")
        if field is not None:
            where.append(f"field '{field}'")
        message = ": ".join(where + [what]) if where else what
        if fix:
            message = f"{message.rstrip('.')}. Fix: {fix}"
        super().__init__(message)
