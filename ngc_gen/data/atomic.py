"""Atomic file writes: readers see the old file or the complete new one, never a partial one.

A crash or an exception mid-write leaves no half-written cache or annotation behind, so a
later run cannot load a truncated file and the "no cache file on error" promise holds.

The file gets the mode an ordinary ``open(path, "w")`` would give it: a new file 0666 less the
umask (the temp file is opened with ``os.open(..., 0o666)``, so the kernel applies the umask;
``tempfile.mkstemp`` would give 0600 and a colleague could not read a checkpoint), an existing
file keeps its mode.
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path
from typing import BinaryIO, Callable


def _open_temp(path: Path) -> tuple[int, str]:
    """A new, empty temp file beside ``path``, created 0666 less the umask (O_EXCL: never an
    existing one). Returns its descriptor and name."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
    for _ in range(100):
        tmp = str(path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp")
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary file name beside {path}")


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], None]) -> Path:
    """Write ``path`` through ``write(fileobj)`` into a temp file in the same folder, then
    ``os.replace`` it into place (atomic on POSIX and Windows within one file system).

    The folder is created if needed; the temp file is removed if ``write`` raises (an OSError
    without a file name, such as a full disk, is raised again naming ``path``). A new file is
    0666 less the umask, a replaced one keeps its mode (as ``open(path, "w")`` would).
    Returns the final path.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = _open_temp(path)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.chmod(tmp, stat.S_IMODE(os.stat(path).st_mode))
        except FileNotFoundError:
            pass  # a new file: the umask already applied at creation
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
