"""Off-screen renders of mesh grids with pyvista (headless: EGL, no window)."""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import trimesh

log = logging.getLogger(__name__)

COLORS = ("#c8a27a", "#7fa7c9", "#9cc28c", "#d08c8c")


def _poly(pv, mesh: trimesh.Trimesh):
    """Geometry only: pv.wrap would also copy trimesh's metadata (a PLY header pyvista warns
    it cannot store)."""
    return pv.PolyData.from_regular_faces(np.asarray(mesh.vertices, dtype=float),
                                          np.asarray(mesh.faces))


def render_grid(rows: list[list], path, labels: list[str] | None = None,
                col_titles: list[str] | None = None, cell: tuple[int, int] = (320, 260),
                view: tuple = (1.0, -1.6, 0.9), up: tuple = (0, 0, 1),
                frame: str = "cell", titles: list[list[str]] | None = None) -> Path:
    """Render rows x columns of meshes into one PNG, atomically. A cell is a mesh, None
    (empty) or a pair (mesh, overlay) whose overlay (e.g. GC surfaces) is drawn translucent.

    Each column gets its own colour; every cell uses the same camera direction `view` so
    shapes can be compared side by side. `frame="cell"` fits the camera to each mesh;
    `frame="row"` to the bounds of its whole row, so before/after pairs keep one scale.
    `titles[i][j]` names one cell (after the row label / column title, if any)."""
    if frame not in ("cell", "row"):
        raise ValueError(f"frame must be 'cell' or 'row', got {frame!r}")
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    n_rows, n_cols = len(rows), max(len(r) for r in rows)
    p = pv.Plotter(off_screen=True, shape=(n_rows, n_cols),
                   window_size=(cell[0] * n_cols, cell[1] * n_rows), border=False)
    p.set_background("white")
    for i, row in enumerate(rows):
        meshes = [m[0] if isinstance(m, tuple) else m for m in row]
        meshes = [m for m in meshes if m is not None and len(m.faces)]
        row_bounds = (np.stack([m.bounds for m in meshes]) if meshes else None)
        for j, mesh in enumerate(row):
            p.subplot(i, j)
            if isinstance(mesh, tuple):
                mesh, overlay = mesh
                p.add_mesh(_poly(pv, overlay), color="#4a78c2", opacity=0.25)
            if mesh is not None and len(mesh.faces):
                p.add_mesh(_poly(pv, mesh), color=COLORS[j % len(COLORS)], smooth_shading=True)
                b = mesh.bounds if frame == "cell" else np.stack(
                    [row_bounds[:, 0].min(0), row_bounds[:, 1].max(0)])
                c = b.mean(0)
                r = float(np.linalg.norm(b[1] - b[0])) * 1.3
                d = np.asarray(view, dtype=float)
                p.camera_position = [tuple(c + r * d / np.linalg.norm(d)), tuple(c), tuple(up)]
            title = []
            if col_titles and i == 0 and j < len(col_titles):
                title.append(col_titles[j])
            if labels and j == 0 and i < len(labels):
                title.append(labels[i])
            if titles and i < len(titles) and j < len(titles[i]) and titles[i][j]:
                title.append(titles[i][j])
            if title:
                p.add_text(" / ".join(title), font_size=9, color="black")
    p.render()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    p.screenshot(str(tmp))
    p.close()
    os.replace(tmp, path)
    return path


def render_gallery(meshes: list, names: list[str], path, per_row: int = 4, **kwargs) -> Path:
    """Meshes in rows of `per_row`, each cell titled with its name."""
    rows = [meshes[i:i + per_row] for i in range(0, len(meshes), per_row)]
    titles = [names[i:i + per_row] for i in range(0, len(names), per_row)]
    return render_grid(rows, path, titles=titles, **kwargs)


def render_or_warn(render, path, *args, **kwargs) -> Path | None:
    """`render(*args, path, ...)`, but a failure (e.g. no off-screen OpenGL on this machine) is
    logged, not raised: a picture is a convenience beside outputs already written."""
    try:
        return render(*args, path, **kwargs)
    except Exception as e:  # noqa: BLE001
        log.warning("could not render %s: %s", path, e)
        return None
