"""A command owns its run directory while it works (`ngc_gen.app.runtime.lock`): a second
command on it is refused at once with one line naming the owner, a lock left by a killed run is
taken over (tests/app/test_resume.py kills real runs and resumes them), and a refused command
leaves the owner's directory alone."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time

import pytest

from ngc_gen import workspace
from ngc_gen.app.runtime.lock import RunDirInUse, RunLock, lock_run_dir

from ..helpers import ROOT, run_entry

HOLD = """
import sys, time
from pathlib import Path
from ngc_gen.app.runtime.lock import RunLock
RunLock(Path(sys.argv[1])).acquire()
print("held", flush=True)
time.sleep(120)
"""


def test_a_second_lock_is_refused_naming_the_owner(tmp_path):
    first = RunLock(tmp_path).acquire()
    with pytest.raises(RunDirInUse, match=rf"in use by pid {os.getpid()} on "
                                          rf"{socket.gethostname()} since "):
        RunLock(tmp_path).acquire()
    first.release()
    assert not workspace.lock(tmp_path).exists()
    RunLock(tmp_path).acquire().release()  # free again once released


def test_a_stale_lock_is_taken_over(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    workspace.lock(tmp_path).write_text(json.dumps(
        {"pid": int(dead), "host": socket.gethostname(), "started": "earlier",
         "command": "train.py (killed)"}))
    lock = RunLock(tmp_path).acquire()
    assert json.loads(workspace.lock(tmp_path).read_text())["pid"] == os.getpid()
    lock.release()


def test_distributed_ranks_other_than_zero_do_not_lock(tmp_path, monkeypatch):
    cfg = {"run_dir": str(tmp_path)}
    monkeypatch.setenv("LOCAL_RANK", "1")
    assert lock_run_dir(cfg) is None
    monkeypatch.setenv("LOCAL_RANK", "0")
    lock = lock_run_dir(cfg)
    assert lock is not None
    lock.release()


def test_a_second_command_on_a_run_in_use_exits_2_naming_the_owner(tmp_path):
    run = tmp_path / "run"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(run)], cwd=ROOT, env=env,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        (run / "keep.txt").write_text("the owner's")
        r = run_entry("train.py", "stage=fit", "data=ant", f"hydra.run.dir={run}",
                      cwd=tmp_path, timeout=120)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.rstrip("\n").split("\n")
        assert len(lines) == 1, r.stderr
        assert lines[0].startswith(f"error: {run} is in use by pid {holder.pid} on "), lines[0]
        assert (run / "keep.txt").read_text() == "the owner's"
        assert json.loads(workspace.lock(run).read_text())["pid"] == holder.pid
        assert "checkpoints" not in {p.name for p in run.iterdir()}
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.slow
def test_the_first_of_two_identical_fits_finishes_as_if_alone(tmp_path):
    """Two identical fits on one directory, the second started while the first runs: the
    second exits 2 at once, the first's metrics equal those of the same fit run alone."""
    args = ["stage=fit", "data=ant", "model=small", "trainer.max_steps=40",
            "extract.resolution=32", "trainer.enable_progress_bar=false", "threads=1"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = tmp_path / "shared"
    first = subprocess.Popen([sys.executable, str(ROOT / "train.py"), *args,
                              f"hydra.run.dir={run}"], cwd=ROOT, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while not workspace.lock(run).exists() and time.time() < deadline:
        time.sleep(0.05)
    second = run_entry("train.py", *args, f"hydra.run.dir={run}", timeout=120)
    assert second.returncode == 2 and "is in use by pid" in second.stderr, second.stderr
    assert first.wait(timeout=900) == 0, first.stderr.read()[-2000:]
    alone = run_entry("train.py", *args, f"hydra.run.dir={tmp_path / 'alone'}", timeout=900)
    assert alone.returncode == 0, alone.stderr[-2000:]
    shared = json.loads(workspace.metrics(run).read_text())
    single = json.loads(workspace.metrics(tmp_path / "alone").read_text())
    assert shared["mean"]["cd"] == single["mean"]["cd"] > 0
    assert shared["mean"]["fscore"] == single["mean"]["fscore"]
    assert not workspace.lock(run).exists()


def test_a_folder_the_lock_made_goes_when_nothing_was_written(tmp_path):
    empty = RunLock(tmp_path / "a" / "b").acquire()
    empty.release()
    assert list(tmp_path.iterdir()) == []
    used = RunLock(tmp_path / "c" / "d").acquire()
    (tmp_path / "c" / "d" / "metrics.json").write_text("{}")
    used.release()
    assert sorted(p.name for p in (tmp_path / "c" / "d").iterdir()) == ["metrics.json"]
