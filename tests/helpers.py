"""Helpers shared by tests: compose the real Hydra configs, run the real entry points."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from ngc_gen.app.runtime.config import compose_config  # noqa: F401  (re-exported for tests)

ROOT = Path(__file__).resolve().parents[1]

#: An ASCII PLY header for one triangle (3 vertices, 1 face): append the vertex and face lines.
PLY_TRIANGLE_HEADER = """ply
format ascii 1.0
element vertex 3
property float x
property float y
property float z
element face 1
property list uchar int vertex_indices
end_header
"""


def run_entry(script: str, *args: str, cwd: Path | None = None, timeout: int = 600):
    """Run `python <script> args...` as a user would; returns the CompletedProcess."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(ROOT / script), *args], cwd=cwd or ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)

