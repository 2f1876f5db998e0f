"""The runner layer's bad-input error: a setting of the command line or config that cannot
work (an unknown stage, a malformed shard, an output folder that cannot be written). Light to
import, so an entry point rejects such a setting before torch loads."""
from __future__ import annotations

import sys


class ConfigError(ValueError):
    """A bad setting: names the key, its value, what is wrong and how to fix it.

        ConfigError("unknown stage", key="stage", value="train", fix="choose one of ...")
        -> "stage = 'train': unknown stage. Fix: choose one of ..."
    """

    def __init__(self, what: str, *, key: str | None = None, value=None, fix: str | None = None):
        self.what, self.key, self.value, self.fix = what, key, value, fix
        message = what if key is None else f"{key} = {value!r}: {what}"
        if fix:
            message = f"{message.rstrip('.')}. Fix: {fix}"
        super().__init__(message)


# (module, class) of the project's bad-input errors (FileNotFoundError too; cli.py adds the
# OSErrors of the machine's state)
USER_ERROR_CLASSES = (("ngc_gen.app.runtime.errors", "ConfigError"),
                      ("ngc_gen.data.errors", "DataError"),
                      ("ngc_gen.edit.errors", "EditError"),
                      ("ngc_gen.geometry.errors", "GeometryError"),
                      ("ngc_gen.extract.budget", "GridTooLarge"))


def user_error_types() -> tuple[type, ...]:
    """The bad-input exception classes of the layers imported so far."""
    found = [getattr(sys.modules[m], c) for m, c in USER_ERROR_CLASSES if m in sys.modules]
    return (*found, FileNotFoundError)
