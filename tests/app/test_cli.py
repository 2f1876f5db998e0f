"""What every entry point shares: `threads=` and user errors as one line with exit code 2."""
import pytest
import torch

from ngc_gen.app.runtime.cli import auto_threads, run_job, set_threads
from ngc_gen.app.runtime.errors import ConfigError

from ..helpers import run_entry


def test_set_threads_sets_torch_and_null_keeps_it():
    before = torch.get_num_threads()
    try:
        set_threads(1)
        assert torch.get_num_threads() == 1
        set_threads(None)
        assert torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize("cores,load,expected", [
    (2, 0.1, 2), (2, 0.6, 1), (2, 1.0, 1), (2, 7.5, 1), (8, 2.4, 6), (1, 0.0, 1)])
def test_auto_threads_leaves_the_busy_cores_to_the_other_jobs(cores, load, expected):
    # two torch threads on 2 cores with one other busy process run a training step 4x slower
    # than one thread: auto must fall back to one thread as soon as another job runs
    assert auto_threads(cores, load) == expected


def test_threads_auto_sets_a_count_within_the_cores():
    before = torch.get_num_threads()
    try:
        n = set_threads("auto")
        assert 1 <= n <= (__import__("os").cpu_count() or 1) and torch.get_num_threads() == n
    finally:
        torch.set_num_threads(before)


def test_bad_threads_is_a_user_error():
    with pytest.raises(ConfigError, match="threads must be >= 1"):
        set_threads(0)
    with pytest.raises(SystemExit) as e:
        run_job(lambda cfg: pytest.fail("ran with bad threads"), {"threads": -2})
    assert e.value.code == 2


@pytest.mark.parametrize("script", ["train.py", "sample.py", "edit.py"])
def test_entry_points_reject_bad_threads(script, tmp_path):
    r = run_entry(script, "threads=0", f"hydra.run.dir={tmp_path}/run")
    assert r.returncode == 2 and "threads must be >= 1" in r.stderr
    assert "Traceback" not in r.stderr
    run = tmp_path / "run"  # at most Hydra's own record of the call
    left = {p.name for p in run.iterdir()} if run.exists() else set()
    assert left <= {".hydra", "train.log", "sample.log", "edit.log"}, left


def test_busy_cores_reads_the_cpu_time_spent_meanwhile(tmp_path, monkeypatch):
    # /proc/stat's first line: user nice system idle iowait ...; between the two reads the
    # machine spent 150 busy and 50 idle jiffies: 3/4 of every core
    from ngc_gen.app.runtime import cli

    stat = tmp_path / "stat"
    lines = iter(["cpu 100 0 100 1000 0 0 0\n", "cpu 200 0 150 1040 10 0 0\n"])

    def fake_sleep(_):
        stat.write_text(next(lines))

    stat.write_text(next(lines))
    monkeypatch.setattr(cli.time, "sleep", fake_sleep)
    monkeypatch.setattr(cli.os, "cpu_count", lambda: 2)
    assert cli.busy_cores(stat=str(stat)) == pytest.approx(1.5)
    assert cli.auto_threads(2, cli.busy_cores(stat=str(tmp_path / "missing"))) >= 1
