"""Settings checked before the work starts, with light imports only: a run that cannot write its
results or has a malformed setting fails in a second with the setting to change, not after an
hour of preparation, training or extraction."""
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


def trainer_steps(cfg) -> int:
    """trainer.max_steps as an int (ConfigError if it is not a positive whole number)."""
    value = cfg.trainer.get("max_steps")
    try:
        steps = int(value)
    except (TypeError, ValueError):
        steps = 0
    if steps < 1 or str(value).strip() not in (str(steps), f"{steps}.0"):
        raise ConfigError("must be a whole number of optimizer steps >= 1",
                          key="trainer.max_steps", value=value,
                          fix="pass e.g. trainer.max_steps=3000")
    return steps
