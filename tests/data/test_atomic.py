"""The atomic writer: complete files only, and the mode an ordinary write would give."""

import os
import stat

import pytest

from ngc_gen.data.atomic import atomic_write, atomic_write_text


@pytest.fixture
def umask():
    """Set the process umask for one test, restore it after."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda m: os.umask(m)
    os.umask(old)


def _mode(p):
    return stat.S_IMODE(os.stat(p).st_mode)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077])
def test_new_file_gets_the_umask_mode(tmp_path, umask, mask):
    umask(mask)
    ordinary = tmp_path / "ordinary.json"
    ordinary.write_text("{}")
    out = atomic_write_text(tmp_path / "metrics.json", "{}")
    assert _mode(out) == 0o666 & ~mask == _mode(ordinary)  # mkstemp's 0600 fails this


def test_group_and_others_can_read_with_the_usual_umask(tmp_path, umask):
    umask(0o022)
    out = atomic_write(tmp_path / "sub" / "ckpt.pt", lambda f: f.write(b"x"))
    assert _mode(out) & 0o044 == 0o044


def test_replaced_file_keeps_its_mode(tmp_path, umask):
    umask(0o022)
    target = tmp_path / "shared.yaml"
    target.write_text("old")
    os.chmod(target, 0o664)
    atomic_write_text(target, "new")
    assert target.read_text() == "new" and _mode(target) == 0o664


def test_exception_leaves_old_file_and_no_temp(tmp_path):
    target = tmp_path / "keep.txt"
    target.write_text("old")

    def boom(f):
        f.write(b"half")
        raise RuntimeError("mid-write")

    with pytest.raises(RuntimeError):
        atomic_write(target, boom)
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["keep.txt"]
