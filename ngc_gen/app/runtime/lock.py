"""A command owns its run directory while it works: `<run>/.lock` holds an exclusive lock
(`fcntl.flock`) and says who holds it (pid, host, command, start time). A second command on
the same directory is refused at once with one line naming the owner; the first goes on as if
alone. The kernel drops the lock when its process ends, however it ends (kill -9 included), so
a lock file left by a killed run is simply taken over and the same command resumes.

Only the process that starts a job locks: the ranks a distributed run starts (RANK,
LOCAL_RANK, SLURM_PROCID set and not 0) work inside the directory their rank 0 holds. Where
the platform has no `fcntl` (Windows) nothing is locked.
"""
from __future__ import annotations

import json
import os
import socket
import sys
import time
from pathlib import Path

from ngc_gen import workspace

from .errors import ConfigError

RANK_VARIABLES = ("RANK", "LOCAL_RANK", "SLURM_PROCID")


class RunDirInUse(ConfigError):
    """Another command holds the run directory."""


def owned_dir(cfg) -> Path | None:
    """The directory a command writes its run into: train.py's `run_dir`, edit.py's and
    sample.py's `out_dir` when it is set (edit.py's default is a new dated folder, the editor
    writes only on save: nothing to share)."""
    from omegaconf import OmegaConf

    if not OmegaConf.is_config(cfg):
        cfg = OmegaConf.create(cfg)
    if cfg.get("viewer"):
        return None
    for key in ("run_dir", "out_dir"):
        # None where it names Hydra's run directory outside a Hydra job (a config composed
        # from Python): no command owns a directory then
        value = OmegaConf.select(cfg, key, default=None, throw_on_resolution_failure=False)
        if value:
            return Path(str(value))
    return None


def _rank_zero() -> bool:
    return all(os.environ.get(v, "0") in ("", "0") for v in RANK_VARIABLES)


def _owner(path: Path) -> str:
    try:
        d = json.loads(path.read_text())
        return (f"pid {d['pid']} on {d['host']} since {d['started']} "
                f"({d.get('command', '?')})")
    except (OSError, ValueError, KeyError, TypeError):
        return "another command (its lock file is unreadable)"


class RunLock:
    """The exclusive lock on one run directory, held until `release()` or the process ends."""

    def __init__(self, run_dir: Path):
        self.path = workspace.lock(run_dir)
        self.fd: int | None = None
        self.made: list[Path] = []  # the folders acquire() created, deepest first

    def acquire(self) -> "RunLock":
        """Take the lock, or RunDirInUse naming its holder."""
        import fcntl

        folder = self.path.parent
        while not folder.exists() and folder.parent != folder:
            self.made.append(folder)
            folder = folder.parent
        self.path.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise RunDirInUse(
                    f"{self.path.parent} is in use by {_owner(self.path)}",
                    fix="wait for it to finish, or pass another hydra.run.dir / out_dir") \
                    from None
            try:  # the file may have been released and removed while we opened it: retry
                if os.stat(self.path).st_ino == os.fstat(fd).st_ino:
                    break
            except FileNotFoundError:
                pass
            os.close(fd)
        record = {"pid": os.getpid(), "host": socket.gethostname(),
                  "started": time.strftime("%Y-%m-%d %H:%M:%S"),
                  "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:300]}
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps(record).encode())
        self.fd = fd
        return self

    def release(self) -> None:
        """Remove the lock file and drop the lock (the file goes first, so a command that
        opens it meanwhile sees it was removed and retries), then the folders acquire() made
        if nothing was written into them (a command that failed leaves no empty run behind)."""
        if self.fd is None:
            return
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        os.close(self.fd)
        self.fd = None
        for folder in self.made:
            try:
                folder.rmdir()
            except OSError:  # something was written into it: a run
                break


def lock_run_dir(cfg) -> RunLock | None:
    """The lock on the command's run directory (`owned_dir`), taken now; None when the command
    has no shared directory, is a rank other than 0, the platform cannot lock, or the folder
    cannot be written (the command's own check reports that, naming its setting)."""
    run_dir = owned_dir(cfg)
    if run_dir is None or not _rank_zero():
        return None
    try:
        import fcntl  # noqa: F401
    except ImportError:
        return None
    try:
        return RunLock(run_dir).acquire()
    except RunDirInUse:
        raise
    except OSError:  # a folder that cannot be made or written: the command's own check says so
        return None
