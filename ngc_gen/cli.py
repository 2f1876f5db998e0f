"""What the thin entry points share: turning user errors into one clear line and exit code 2."""
from __future__ import annotations

import sys
from contextlib import contextmanager

from ngc_gen.data.errors import DataError
from ngc_gen.edit.errors import EditError
from ngc_gen.geometry import GeometryError

USER_ERRORS = (DataError, GeometryError, EditError, FileNotFoundError)


@contextmanager
def user_errors():
    """Print bad-input errors as `error: <message>` (no traceback) and exit with status 2."""
    try:
        yield
    except USER_ERRORS as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
