"""Errors raised by the geometry layer."""


class GeometryError(ValueError):
    """An invalid curve or generalized cylinder; names the GC and field at fault."""

    def __init__(self, message: str, gc_name: str | None = None, field: str | None = None):
        where = ""
        if gc_name is not None:
            where = f"GC '{gc_name}'" + (f", field '{field}'" if field else "") + ": "
        elif field is not None:
            where = f"field '{field}': "
        super().__init__(where + message)
        self.gc_name = gc_name
        self.field = field
