"""The installed package, away from the checkout, still has what edit.py needs from it."""
import shutil
import subprocess
import sys

import pytest

from ..helpers import ROOT


@pytest.mark.slow  # builds and installs a wheel (~20 s)
def test_installed_wheel_finds_the_edit_programs(tmp_path):
    src, wheels, target = tmp_path / "src", tmp_path / "wheels", tmp_path / "site"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "ngc_gen", src / "ngc_gen",
                    ignore=shutil.ignore_patterns("__pycache__"))
    pip = [sys.executable, "-m", "pip", "-q"]
    subprocess.run([*pip, "wheel", str(src), "--no-deps", "--no-build-isolation", "-w",
                    str(wheels)], check=True, capture_output=True, timeout=600)
    wheel = next(wheels.glob("*.whl"))
    subprocess.run([*pip, "install", "--no-deps", "--target", str(target), str(wheel)],
                   check=True, capture_output=True, timeout=600)
    code = ("import ngc_gen; from ngc_gen.app.runtime.programs import available_programs; "
            "print(ngc_gen.__file__); print(' '.join(available_programs()))")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"},
                       timeout=300)
    assert r.returncode == 0, r.stderr
    where, programs = r.stdout.splitlines()
    assert where.startswith(str(target))  # the installed copy, not the checkout
    assert set(programs.split()) == {p.stem for p in (ROOT / "ngc_gen/conf/edit").glob("*.yaml")}
