"""Helpers shared by tests: compose the real Hydra configs, run the real entry points."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from hydra import compose, initialize_config_dir

import ngc_gen.config  # noqa: F401  (resolvers)

ROOT = Path(__file__).resolve().parents[1]


def compose_config(config_name: str = "train", overrides: list[str] | None = None):
    with initialize_config_dir(version_base="1.3", config_dir=str(ROOT / "conf")):
        return compose(config_name=config_name, overrides=overrides or [])


def run_entry(script: str, *args: str, cwd: Path | None = None, timeout: int = 600):
    """Run `python <script> args...` as a user would; returns the CompletedProcess."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(ROOT / script), *args], cwd=cwd or ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)
