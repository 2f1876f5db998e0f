"""Off-screen renders of mesh grids with pyvista (headless: EGL, no window)."""
from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import trimesh

from .screenshot import save_screenshot

log = logging.getLogger(__name__)

COLORS = ("#c8a27a", "#7fa7c9", "#9cc28c", "#d08c8c")


def _poly(pv, mesh: trimesh.Trimesh):
    """Geometry only: pv.wrap would also copy trimesh's metadata (a PLY header pyvista warns
    it cannot store)."""
    return pv.PolyData.from_regular_faces(np.asarray(mesh.vertices, dtype=float),
                                          np.asarray(mesh.faces))


def _cell_parts(cell):
    """(mesh, overlay, labels) of a cell: a mesh, None, (mesh, overlay) or (mesh, overlay,
    labels) with labels a list of (text, (3,) point)."""
    if isinstance(cell, tuple):
        mesh, overlay, *rest = cell
        return mesh, overlay, (rest[0] if rest else None) or []
    return cell, None, []


def _per_row(value, n_rows: int, what: str) -> list:
    """A setting given once for the grid or as a list with one entry per row."""
    if isinstance(value, list) and value and not isinstance(value[0], (int, float)):
        if len(value) != n_rows:
            raise ValueError(f"{what} has {len(value)} entries for {n_rows} rows")
        return value
    return [value] * n_rows


LABEL_CHAR_PX, LABEL_H_PX = 7.0, 16.0  # a font_size 8 label's box: width per character, height


def label_boxes(texts: list[str]) -> np.ndarray:
    """(N, 2) pixel width and height of each label's box (font_size 8 with its padding)."""
    return np.array([[LABEL_CHAR_PX * len(t) + 8.0, LABEL_H_PX] for t in texts], dtype=float)


def spread_labels(xy: np.ndarray, sizes: np.ndarray, width: float, height: float,
                  steps: int = 24) -> np.ndarray:
    """Label positions (N, 2) in pixels, moved from their points `xy` (N, 2) just far enough
    that no two boxes (`sizes` (N, 2), centred on the position) overlap: each label in turn
    (from the top) takes the nearest free slot of a search over vertical, then sideways
    offsets, inside [0, width] x [0, height]; a label with no free slot keeps its point."""
    xy, sizes = np.asarray(xy, dtype=float), np.asarray(sizes, dtype=float)
    placed: list[tuple[np.ndarray, np.ndarray]] = []
    out = xy.copy()
    offsets = [(0.0, 0.0)]
    for k in range(1, steps + 1):
        for dx in (0.0, 0.5, -0.5, 1.0, -1.0):
            offsets += [(dx, k), (dx, -k)]
    for i in np.argsort(-xy[:, 1], kind="stable"):
        half = sizes[i] / 2 + 1.0
        for dx, dy in offsets:
            c = xy[i] + np.array([dx * sizes[i, 0], dy * sizes[i, 1]])
            c = np.clip(c, half, np.maximum(half, [width - half[0], height - half[1]]))
            if all(np.any(np.abs(c - q) >= half + h) for q, h in placed):
                out[i] = c
                placed.append((c, half))
                break
        else:
            placed.append((out[i], half))
    return out


def _spread_in_view(p, points: np.ndarray, texts: list[str], cell,
                    centre: bool = False) -> np.ndarray:
    """World positions for the labels of `points` in the current subplot's camera, moved on
    screen by `spread_labels` so that none overlaps another (same depth as its point): the
    anchor VTK draws a label from, or (`centre`) the middle of its box."""
    m = p.renderer.GetActiveCamera().GetCompositeProjectionTransformMatrix(
        cell[0] / cell[1], -1, 1)
    M = np.array([[m.GetElement(r, c) for c in range(4)] for r in range(4)])
    h = np.c_[points, np.ones(len(points))] @ M.T
    ndc = h[:, :3] / h[:, 3:4]
    px = (ndc[:, :2] + 1) / 2 * np.array(cell, dtype=float)
    sizes = label_boxes(texts)
    moved = spread_labels(px, sizes, float(cell[0]), float(cell[1]))
    anchor = moved if centre else moved - sizes / 2  # VTK draws a box up and right of it
    ndc2 = np.c_[anchor / np.array(cell, dtype=float) * 2 - 1, ndc[:, 2], np.ones(len(points))]
    w = ndc2 @ np.linalg.inv(M).T
    return w[:, :3] / w[:, 3:4]


def _title(i: int, j: int, labels, col_titles, titles) -> str:
    """Cell (i, j)'s title: its column title (first row), row label (first column) and own
    title, joined by ' / '; '' for none."""
    parts = []
    if col_titles and i == 0 and j < len(col_titles):
        parts.append(col_titles[j])
    if labels and j == 0 and i < len(labels):
        parts.append(labels[i])
    if titles and i < len(titles) and j < len(titles[i]) and titles[i][j]:
        parts.append(titles[i][j])
    return " / ".join(parts)


def render_grid(rows: list[list], path, labels: list[str] | None = None,
                col_titles: list[str] | None = None, cell: tuple[int, int] = (320, 260),
                view=None, up="auto", frame: str = "cell",
                titles: list[list[str]] | None = None, margin: float = 0.04) -> Path:
    """Render rows x columns of meshes into one PNG, atomically. A cell is a mesh, None
    (empty), a pair (mesh, overlay) whose overlay (e.g. GC surfaces) is drawn translucent, or
    a triple (mesh, overlay, point labels [(text, (3,) point), ...]) (`gc_labels`).

    Each column gets its own colour. A row has one camera direction, so its shapes compare
    side by side: `view` (a world direction toward the camera) or, None, the side view of the
    row's shapes (`camera.side_view`) about its up axis. `up`: 'auto' (`camera.resolve_up`
    over the row's meshes), an axis name ('y', '-z') or a vector. `view` and `up` may also
    be lists with one entry per row. The camera distance frames the whole shape and overlay
    (`camera.frame_points`): nothing is cut at the cell's edges, with `margin` (a fraction
    of the cell) free on each side and room for the cell's title. `frame="cell"` fits each
    cell; `frame="row"` fits every cell to its whole row, so before/after keep one scale.
    `titles[i][j]` names one cell (after the row label / column title, if any)."""
    from .camera import VIEW_ANGLE, frame_points, resolve_up, side_view

    if frame not in ("cell", "row"):
        raise ValueError(f"frame must be 'cell' or 'row', got {frame!r}")
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    n_rows, n_cols = len(rows), max(len(r) for r in rows)
    views, ups = _per_row(view, n_rows, "view"), _per_row(up, n_rows, "up")
    title_px = 18  # a title line (12 px text) at the cell's top
    p = pv.Plotter(off_screen=True, shape=(n_rows, n_cols),
                   window_size=(cell[0] * n_cols, cell[1] * n_rows), border=False)
    p.set_background("white")
    for i, row in enumerate(rows):
        parts = [_cell_parts(c) for c in row]
        shown = [(m, o) for m, o, _ in parts if m is not None and len(m.faces)]
        u = resolve_up(ups[i], [m for m, _ in shown])
        row_points = [np.concatenate([np.asarray(m.vertices)] +
                                     ([np.asarray(o.vertices)] if o is not None else []))
                      for m, o in shown]
        row_points = np.concatenate(row_points) if row_points else np.zeros((0, 3))
        d = (side_view(row_points, u) if views[i] is None
             else np.asarray(views[i], dtype=float) / np.linalg.norm(views[i]))
        row_titles = [_title(i, j, labels, col_titles, titles) for j in range(len(row))]
        for j, (mesh, overlay, point_labels) in enumerate(parts):
            p.subplot(i, j)
            title = row_titles[j]
            if title:
                # fixed 12 px text (a corner annotation would scale short titles up)
                p.add_text(title, position=(4, cell[1] - title_px + 2), font_size=6,
                           color="black")
            if overlay is not None:
                p.add_mesh(_poly(pv, overlay), color="#4a78c2", opacity=0.25)
            if mesh is None or not len(mesh.faces):
                continue
            p.add_mesh(_poly(pv, mesh), color=COLORS[j % len(COLORS)], smooth_shading=True)
            pts = row_points if frame == "row" else np.concatenate(
                [np.asarray(mesh.vertices)] + ([np.asarray(overlay.vertices)]
                                               if overlay is not None else []))
            band = any(row_titles) if frame == "row" else bool(title)  # row: one scale
            free_h = 1 - 2 * margin - (2 * title_px / cell[1] if band else 0.0)
            c, dist = frame_points(pts, d, u, aspect=cell[0] / cell[1], view_angle=VIEW_ANGLE,
                                   fill=(1 - 2 * margin, free_h))
            p.camera.view_angle = VIEW_ANGLE
            p.camera_position = [tuple(c + dist * d), tuple(c), tuple(u)]
            p.reset_camera_clipping_range()
            if point_labels:  # names moved apart on screen, a line back to each GC's point
                at = np.array([q for _, q in point_labels], dtype=float)
                texts = [str(t) for t, _ in point_labels]
                shown_at = _spread_in_view(p, at, texts, cell)
                p.add_points(at, color="black", point_size=5, render_points_as_spheres=True,
                             reset_camera=False)
                p.add_lines(np.stack([at, _spread_in_view(p, at, texts, cell, centre=True)], 1)
                            .reshape(-1, 3), color="#555555", width=1)
                names = p.add_point_labels(
                    shown_at, texts, font_size=8, show_points=False, shape_opacity=0.7,
                    shape_color="white", text_color="black", always_visible=True,
                    reset_camera=False)
                names.GetMapper().PlaceAllLabelsOn()  # VTK drops overlapping ones otherwise
                p.reset_camera_clipping_range()
    return save_screenshot(p, path)


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
