"""What kind of run a checkpoint is from, read without torch: the entry points refuse a
checkpoint of the wrong stage (a diffusion run given to edit.py, a fit run to sample.py) in a
second, before torch loads.

A torch checkpoint is a zip whose `data.pkl` holds the dict Lightning saved. It is read with an
unpickler that builds nothing of the file's choosing: every class it names becomes an inert
stub, tensors are not read. So a crafted file can run no code here; `load_checkpoint_dict`
(weights_only=True) still loads the real thing later.
"""
from __future__ import annotations

import collections
import io
import pickle
import zipfile
from pathlib import Path

from ngc_gen import workspace
from ngc_gen.data.errors import DataError

from .kinds import KINDS


class _Stub(dict):
    """Whatever the pickle names (a tensor rebuild, a Lightning AttributeDict): an empty dict
    that takes any arguments and any state."""

    def __init__(self, *args, **kwargs):
        super().__init__()

    def __setstate__(self, state):
        if isinstance(state, dict):
            self.update(state)


class _Peek(pickle.Unpickler):
    def find_class(self, module, name):
        if (module, name) == ("collections", "OrderedDict"):
            return collections.OrderedDict
        return _Stub

    def persistent_load(self, pid):
        return None  # a tensor's storage: not read


class NotACheckpoint(ValueError):
    """The file is not a torch checkpoint (not a zip holding data.pkl)."""


def checkpoint_kind(path) -> str | None:
    """`hyper_parameters.checkpoint_kind` of the checkpoint at `path` (None if it records none).
    NotACheckpoint if the file is not a readable torch zip checkpoint."""
    hp = checkpoint_hyper(path)
    return hp.get("checkpoint_kind") if isinstance(hp, dict) else None


def checkpoint_hyper(path) -> dict | None:
    """The `hyper_parameters` dict of the checkpoint at `path` (its tensors not read; None if
    it has none). NotACheckpoint if the file is not a readable torch zip checkpoint."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as z:
            names = [n for n in z.namelist() if n.endswith("data.pkl")]
            if not names:
                raise NotACheckpoint("a zip file without the data.pkl of a torch checkpoint")
            data = z.read(min(names, key=len))
        obj = _Peek(io.BytesIO(data)).load()
    except NotACheckpoint:
        raise
    except (zipfile.BadZipFile, EOFError, pickle.UnpicklingError, ValueError, KeyError,
            IndexError, TypeError, AttributeError) as e:
        raise NotACheckpoint(f"{type(e).__name__}: {str(e).splitlines()[0][:120] if str(e) else 'unreadable'}") from None
    if not isinstance(obj, dict):
        return None
    hp = obj.get("hyper_parameters")
    return hp if isinstance(hp, dict) else None


def resolve_checkpoint(path, fix: str, what: str) -> Path:
    """A checkpoint file, or `<dir>/checkpoints/last.ckpt` for a run directory."""
    if path is None or str(path) in ("", "???"):
        raise DataError(f"no {what} given", fix=fix)
    path = Path(path)
    if path.is_dir():
        ckpt = workspace.last_checkpoint(path)
        if not ckpt.is_file():
            raise DataError(f"{path} holds no checkpoints/last.ckpt (is it a finished "
                            f"{what}?)", path=path, fix=fix)
        return ckpt
    if not path.is_file():
        raise DataError(f"{what} {path} does not exist", fix=fix)
    return path


def check_kind(path: Path, kinds: dict[str, str], fix: str) -> str:
    """The kind of the checkpoint at `path`, which must be one of `kinds` ({kind: what it is,
    e.g. "a fit run"}); DataError (before torch loads) naming the kind found otherwise."""
    try:
        kind = checkpoint_kind(path)
    except NotACheckpoint as e:
        raise DataError(f"{path} is not a loadable checkpoint ({e})", fix=fix) from None
    if kind not in kinds:
        found = KINDS.get(kind, f"an unknown kind ({kind!r})")
        raise DataError(f"{path} is a checkpoint of {found}, not of "
                        f"{' or '.join(kinds.values())}", fix=fix)
    return kind

