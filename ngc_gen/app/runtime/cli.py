"""What the thin entry points share: torch's thread count from the config, and bad input of any
kind (a config Hydra cannot compose, a user error of a runner, a disk that is full or not
writable) as one line `error: ...` with exit code 2, and no run directory left behind.

Nothing heavy is imported here: an entry point rejects a bad command line or edit program in
about a second, before torch and Lightning load (the error types of the layers are recognised
through `sys.modules`: an error of a module that was never imported cannot have been raised).
"""
from __future__ import annotations

import errno
import logging
import os
import re
import shutil
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from ngc_gen import workspace

from .checks import check_threads
from .errors import user_error_types
from .lock import RunDirInUse, lock_run_dir

log = logging.getLogger(__name__)

# OS errors that are the machine's state, not a bug: a full disk, a read-only or missing folder
ENVIRONMENT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                      errno.ENOTDIR, errno.EISDIR, errno.EEXIST}


def os_error_message(e: OSError) -> str:
    """One line for an OS error of the environment: what failed, where, and what to do."""
    where = f" {e.filename}" if e.filename else ""
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return (f"cannot write{where}: {e.strerror or e}. Fix: free disk space, or write "
                f"elsewhere (hydra.run.dir / out_dir / prepare.cache_dir)")
    return (f"cannot use{where}: {e.strerror or e}. Fix: check the path and its permissions, or "
            f"choose another folder (hydra.run.dir / out_dir / prepare.cache_dir)")


def one_line_message(e: BaseException) -> str | None:
    """The one-line message of a bad-input error, or None if `e` is a bug (traceback)."""
    from omegaconf.errors import InterpolationToMissingValueError, MissingMandatoryValue

    if isinstance(e, user_error_types()):
        return " ".join(str(e).split("\n"))
    if isinstance(e, (MissingMandatoryValue, InterpolationToMissingValueError)):
        # the ??? key itself, also when it was met resolving another key (data.name: ${.path})
        named = re.search(r"Missing mandatory value: (\S+)", str(e))
        key = named.group(1) if named else (getattr(e, "full_key", None)
                                            or str(e).split(":")[-1].strip())
        return f"{key} is not set (??? in the config). Fix: pass {key}=<value>"
    if isinstance(e, OSError) and e.errno in ENVIRONMENT_ERRNOS:
        return os_error_message(e)
    return None


def hydra_message(e: BaseException) -> str | None:
    """One line for a config Hydra could not compose (unknown key, group option or syntax)."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    if not isinstance(e, (HydraException, OmegaConfBaseException)):
        return None
    from hydra.errors import MissingConfigException, OverrideParseException

    text = str(e)
    if isinstance(e, OverrideParseException):
        return (f"cannot parse the override {e.override!r} ({text.splitlines()[0]}). Fix: write "
                f"key=value, a list as key=[a,b]; quote a value with brackets or commas")
    if isinstance(e, MissingConfigException) and "Available options in" in text:
        head, _, rest = text.partition("Available options in")
        group, _, options = rest.partition(":")
        names = [o.strip() for o in options.split("Config search path")[0].split() if o.strip()]
        return (f"{head.strip().split(': ', 1)[-1].rstrip('.')}. Fix: choose one of "
                f"{group.strip().strip(chr(39))}={' | '.join(names)}")
    lines = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("Config search path"):
            break
        if line and not line.startswith(("provider=", "See https://")):
            lines.append(line.rstrip("."))
    text = "; ".join(lines)
    cause = e.__cause__
    override = re.match(r"Could not override '([^']+)'", str(e))
    if override and cause is not None and "not in struct" in str(cause):
        key = override.group(1)
        return (f"unknown config key '{key}'. Fix: check its spelling (`--help` lists every "
                f"key), or add a new key with +{key}=<value>")
    if cause is not None:
        text += f" ({str(cause).splitlines()[0]})"
    return text


# what a run directory holds before a stage has made anything: Hydra's record of the call and
# the stage's record of its settings (config.yaml, seeds.json)
RECORD_ONLY = {".hydra", workspace.CONFIG, workspace.SEEDS}


def discard_hydra_record() -> None:
    """Remove the run directory Hydra made for this job when it holds nothing but the record of
    the call (.hydra/, <job>.log, config.yaml, seeds.json), and the empty folders above it up
    to the working directory: a command that failed on bad input leaves no run behind."""
    try:
        from hydra.core.hydra_config import HydraConfig

        hc = HydraConfig.get()
        run, job = Path(hc.runtime.output_dir), hc.job.name
    except Exception:  # noqa: BLE001  (not inside a Hydra job: nothing Hydra made)
        return
    cwd = Path.cwd().resolve()
    if not run.is_dir() or run.resolve() == cwd:
        return
    names = {p.name for p in run.iterdir()}
    if ".hydra" not in names or not names <= RECORD_ONLY | {f"{job}.log"}:
        return
    shutil.rmtree(run, ignore_errors=True)
    parent = run.resolve().parent
    while parent != cwd and cwd in parent.parents and not any(parent.iterdir()):
        parent.rmdir()
        parent = parent.parent


def fail(message: str, error: BaseException | None = None) -> None:
    """Print `error: <message>` (and the error's `help` text, if any) and exit with status 2."""
    print(f"error: {message}", file=sys.stderr)
    help_text = getattr(error, "help", None)
    if help_text:
        print(help_text, file=sys.stderr)
    sys.exit(2)


@contextmanager
def user_errors(release=None):
    """Print bad-input errors as `error: <message>` (no traceback), followed by the error's
    `help` text if it has one (the edit-op reference), and exit with status 2. `release()`
    drops what the command holds (its run directory's lock) before the run Hydra made for it
    is discarded; a command refused because another holds the directory discards nothing."""
    try:
        yield
    except Exception as e:  # noqa: BLE001  (only bad input is reported; bugs are re-raised)
        message = one_line_message(e)
        if message is None:
            raise
        if release is not None:
            release()
        if not isinstance(e, RunDirInUse):
            discard_hydra_record()
        fail(message, e)


def busy_cores(window: float = 0.25, stat: str = "/proc/stat") -> float:
    """Cores other processes keep busy now: the machine's busy CPU time over `window` seconds
    (/proc/stat), while this process sleeps. Unlike the 1-minute load average it does not count
    what this process did a moment ago (a `make` setup step, the pipeline's previous stage).
    Falls back to the load average where /proc/stat is missing."""
    def times():
        with open(stat) as f:
            v = [int(x) for x in f.readline().split()[1:]]
        idle = v[3] + (v[4] if len(v) > 4 else 0)   # idle + iowait
        return sum(v) - idle, sum(v)

    try:
        b0, t0 = times()
        time.sleep(window)
        b1, t1 = times()
    except (OSError, ValueError, IndexError):
        return os.getloadavg()[0]
    return (os.cpu_count() or 1) * (b1 - b0) / max(t1 - t0, 1)


def auto_threads(cores: int | None = None, load: float | None = None) -> int:
    """The `threads=auto` rule: the cores no other job is using, at least one. Measured here
    (docs/scaling.md, "Threads, seeds, progress"): on 2 cores, an NGC training step takes 77 ms with one
    thread and 334 ms with two while one other process runs, because torch's two threads wait
    on each other when one is descheduled; on an idle machine two threads are faster. `load`:
    the busy cores (default `busy_cores()`, sampled now)."""
    cores = (os.cpu_count() or 1) if cores is None else int(cores)
    load = busy_cores() if load is None else float(load)
    return max(1, min(cores, cores - int(round(load))))


def set_threads(threads) -> int | None:
    """`threads=N` sets torch's CPU threads; `auto` picks them from the machine's load
    (`auto_threads`); null keeps torch's default (all cores). Returns the count set."""
    threads = check_threads(threads)
    if threads is None:
        return None
    busy = None
    if threads == "auto":
        busy = busy_cores()
        n = auto_threads(load=busy)
    else:
        n = threads
    import torch

    if busy is not None and n != torch.get_num_threads():
        log.info("threads=auto: %d torch thread(s) (%.1f of %d cores busy with other jobs)", n,
                 busy, os.cpu_count() or 1)
    torch.set_num_threads(n)
    return n


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


def run_job(fn, cfg, check=None):
    """What every entry point does: `check(cfg)` (light input checks, before torch loads), own
    the run directory (`lock.lock_run_dir`: a second command on it is refused), set the
    threads, run `fn(cfg)`, report user errors, let the directory go."""
    held = []

    def release():
        while held:
            held.pop().release()

    try:
        with user_errors(release):
            check_threads(cfg.get("threads"))
            if check is not None:
                check(cfg)
            lock = lock_run_dir(cfg)
            if lock is not None:
                held.append(lock)
            set_threads(cfg.get("threads"))
            return fn(cfg)
    finally:
        release()


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
        skip_final_collection()
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
    skip_final_collection()


def skip_final_collection() -> None:
    """At the end of a command: leave the objects alive now to the interpreter's exit, so its
    shutdown does not trace them all once more (with torch loaded, about 1M objects: exiting
    took 0.9 s, 0.1 s with this; measured on `python -c "import torch"`). Exit handlers,
    buffers and files are unaffected: nothing is skipped but the garbage collector's pass."""
    import gc

    gc.freeze()
