"""Atomic file writes: readers see the old file or the complete new one, never a partial one.

A crash or an exception mid-write leaves no half-written cache or annotation behind, so a
later run cannot load a truncated file and the "no cache file on error" promise holds.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import BinaryIO, Callable


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], None]) -> Path:
    """Write ``path`` through ``write(fileobj)`` into a temp file in the same folder, then
    ``os.replace`` it into place (atomic on POSIX and Windows within one file system).

    The folder is created if needed; the temp file is removed if ``write`` raises (an OSError
    without a file name, such as a full disk, is raised again naming ``path``).
    Returns the final path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError) and e.errno is not None and not e.filename:
            # a full disk mid-write: say which file could not be written
            raise OSError(e.errno, e.strerror or os.strerror(e.errno), str(path)) from e
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Atomically write UTF-8 ``text`` to ``path`` (see ``atomic_write``)."""
    return atomic_write(path, lambda f: f.write(text.encode("utf-8")))
