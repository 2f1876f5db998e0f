"""What the thin entry points share: torch's thread count from the config, and bad input of any
kind (a config Hydra cannot compose, a user error of a runner, a disk that is full or not
writable) as one line `error: ...` with exit code 2, and no run directory left behind.

Nothing heavy is imported here: an entry point rejects a bad command line or edit program in
about a second, before torch and Lightning load (the error types of the layers are recognised
through `sys.modules`: an error of a module that was never imported cannot have been raised).
"""
from __future__ import annotations

import errno
import os
import shutil
import sys
from contextlib import contextmanager
from pathlib import Path

# (module, class) of the project's bad-input errors; FileNotFoundError and the OSErrors below too
USER_ERROR_CLASSES = (("ngc_gen.app.errors", "ConfigError"), ("ngc_gen.data.errors", "DataError"), ("ngc_gen.edit.errors", "EditError"),
                      ("ngc_gen.geometry.errors", "GeometryError"))
# OS errors that are the machine's state, not a bug: a full disk, a read-only or missing folder
ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                      errno.ENOTDIR, errno.EISDIR, errno.ENOENT, errno.EEXIST}


def user_error_types() -> tuple[type, ...]:
    """The bad-input exception classes of the layers imported so far."""
    found = [getattr(sys.modules[m], c) for m, c in USER_ERROR_CLASSES if m in sys.modules]
    return (*found, FileNotFoundError)


def os_error_message(e: OSError) -> str:
    """One line for an OS error of the environment: what failed, where, and what to do."""
    where = f" {e.filename}" if e.filename else ""
    fix = ("free disk space, or write elsewhere (hydra.run.dir / out_dir / prepare.cache_dir)"
           if e.errno in (errno.ENOSPC, errno.EDQUOT) else
           "choose a writable directory (hydra.run.dir / out_dir / prepare.cache_dir)")
    return f"cannot write{where}: {e.strerror or e}. Fix: {fix}"


def one_line_message(e: BaseException) -> str | None:
    """The one-line message of a bad-input error, or None if `e` is a bug (traceback)."""
    from omegaconf.errors import MissingMandatoryValue

    if isinstance(e, user_error_types()):
        return " ".join(str(e).split("\n"))
    if isinstance(e, MissingMandatoryValue):
        key = getattr(e, "full_key", None) or str(e).split(":")[-1].strip()
        return f"{key} is not set (??? in the config). Fix: pass {key}=<value>"
    if isinstance(e, OSError) and e.errno in ENVIRONMENT_ERRNOS:
        return os_error_message(e)
    return None


def hydra_message(e: BaseException) -> str | None:
    """One line for a config Hydra could not compose (unknown key, group option or syntax)."""
    from hydra.errors import HydraException
    from omegaconf.errors import ConfigKeyError, OmegaConfBaseException

    if not isinstance(e, (HydraException, OmegaConfBaseException)):
        return None
    lines = []
    for line in str(e).splitlines():
        line = line.strip()
        if line.startswith("Config search path"):
            break
        if line and not line.startswith(("provider=", "See https://")):
            lines.append(line.rstrip("."))
    text = "; ".join(lines)
    text = text.replace("Available options in", "available options in").replace(":; ", ": ")
    cause = e.__cause__
    if isinstance(cause, ConfigKeyError) and "not in struct" in str(cause):
        key = str(cause).split("'")[1] if "'" in str(cause) else "the key"
        return (f"unknown config key '{key}'. Fix: check its spelling (`--help` lists every "
                f"key), or add a new key with +{key}=<value>")
    if cause is not None:
        text += f" ({str(cause).splitlines()[0]})"
    return text


def discard_hydra_record() -> None:
    """Remove the run directory Hydra made for this job when it holds nothing but Hydra's own
    record (.hydra/, <job>.log): a command that failed on bad input leaves no run behind."""
    try:
        from hydra.core.hydra_config import HydraConfig

        hc = HydraConfig.get()
    except (ImportError, ValueError):  # not inside a Hydra job
        return
    run = Path(hc.runtime.output_dir)
    if not run.is_dir() or run.resolve() == Path.cwd().resolve():
        return
    names = {p.name for p in run.iterdir()}
    if ".hydra" in names and names <= {".hydra", f"{hc.job.name}.log"}:
        shutil.rmtree(run, ignore_errors=True)


def fail(message: str, error: BaseException | None = None) -> None:
    """Print `error: <message>` (and the error's `help` text, if any) and exit with status 2."""
    print(f"error: {message}", file=sys.stderr)
    help_text = getattr(error, "help", None)
    if help_text:
        print(help_text, file=sys.stderr)
    sys.exit(2)


@contextmanager
def user_errors():
    """Print bad-input errors as `error: <message>` (no traceback), followed by the error's
    `help` text if it has one (the edit-op reference), and exit with status 2."""
    try:
        yield
    except Exception as e:  # noqa: BLE001  (only bad input is reported; bugs are re-raised)
        message = one_line_message(e)
        if message is None:
            raise
        discard_hydra_record()
        fail(message, e)


def set_threads(threads) -> None:
    """`threads=N`: torch's CPU threads (null keeps torch's default, all cores). One thread is
    often faster on a machine shared with other jobs: two threads then contend for the cores."""
    if threads is None:
        return
    try:
        n = int(threads)
    except (TypeError, ValueError):
        n = 0
    if n < 1:
        from .errors import ConfigError

        raise ConfigError(f"threads must be >= 1, got {threads}", key="threads", value=threads,
                          fix="pass threads=1 (shared machine) or threads=null (all cores)")
    import torch

    torch.set_num_threads(n)


@contextmanager
def torch_threads(n: int):
    """Run the block with `n` torch intra-op threads, then restore the previous count."""
    import torch

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


OURS = "NGC_GEN_HYDRA_ERRORS"


def hydra_entry(main) -> None:
    """Run a `@hydra.main` function as an entry point: the project's resolvers registered, and
    a config Hydra cannot compose (unknown key or option, bad override syntax, a run directory
    it cannot create) reported as one line with exit code 2 instead of Hydra's several lines
    and status 1. HYDRA_FULL_ERROR=1 set by the user keeps Hydra's own report."""
    from .config import register_resolvers

    register_resolvers()
    if os.environ.get("HYDRA_FULL_ERROR") and not os.environ.get(OURS):
        main()
        return
    # Hydra raises instead of printing and exiting 1; the marker tells our own child processes
    # (DDP ranks) that the setting is ours, not the user's
    os.environ.update({"HYDRA_FULL_ERROR": "1", OURS: "1"})
    try:
        main()
    except Exception as e:  # noqa: BLE001
        message = hydra_message(e) or one_line_message(e)
        if message is None:
            raise
        fail(message, e)
