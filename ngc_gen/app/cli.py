"""What the thin entry points share: torch's thread count from the config, and user errors as
one clear line with exit code 2."""
from __future__ import annotations

import sys
from contextlib import contextmanager

import torch

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


def set_threads(threads) -> None:
    """`threads=N`: torch's CPU threads (null keeps torch's default, all cores). One thread is
    often faster on a machine shared with other jobs: two threads then contend for the cores."""
    if threads is None:
        return
    if int(threads) < 1:
        raise DataError(f"threads must be >= 1, got {threads}", field="threads",
                        fix="pass threads=1 (shared machine) or threads=null (all cores)")
    torch.set_num_threads(int(threads))


@contextmanager
def torch_threads(n: int):
    """Run the block with `n` torch intra-op threads, then restore the previous count."""
    previous = torch.get_num_threads()
    torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def run_job(fn, cfg):
    """What every entry point does: set the threads, run `fn(cfg)`, report user errors."""
    with user_errors():
        set_threads(cfg.get("threads"))
        return fn(cfg)
