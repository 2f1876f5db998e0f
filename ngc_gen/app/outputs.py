"""Output folders checked before the work starts: a run that cannot write its results fails in
a second with the setting to change, not after an hour of training or extraction."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import ConfigError


def check_writable(path, key: str) -> Path:
    """`path` (a folder to be written, created later if missing) can be written: its nearest
    existing ancestor is a folder in which a file can be created. Creates nothing that stays.
    ConfigError naming `key` (the setting that chose the folder) otherwise."""
    path = Path(path).expanduser().absolute()
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    fix = f"pass {key}=<a folder you can write>"
    if not probe.is_dir():
        raise ConfigError(f"{probe} is a file, not a folder, so {path} cannot be created",
                          key=key, value=str(path), fix=fix)
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as e:
        raise ConfigError(f"cannot write in {probe} ({e.strerror or e})", key=key,
                          value=str(path), fix=fix) from None
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(f"no permission to write in {probe}", key=key, value=str(path),
                          fix=fix)
    return path
