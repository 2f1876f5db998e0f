"""Write a pyvista plotter's picture atomically: render, save to a temp file, rename, close."""
from __future__ import annotations

import os
from pathlib import Path


def save_screenshot(plotter, path) -> Path:
    """Render `plotter` to `path` (PNG) with no half-written file left if it fails; closes it."""
    plotter.render()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    plotter.screenshot(str(tmp))
    plotter.close()
    os.replace(tmp, path)
    return path
