"""Pictures of one template's GCs on many meshes: one colour per template GC, the same in every
cell, so a part that landed elsewhere (a leg taken for the tail) stands out across a folder."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from .gc_mesh import gc_surface
from .screenshot import save_screenshot

PALETTE = ("#e6194b", "#3cb44b", "#4363d8", "#f58231", "#911eb4", "#42d4f4", "#f032e6",
           "#bfef45", "#469990", "#9a6324", "#800000", "#808000", "#000075", "#fabed4")


def gc_color(index: int) -> str:
    """The colour of the template's GC number `index`."""
    return PALETTE[index % len(PALETTE)]


def render_gc_collection(cells: list[tuple[str, trimesh.Trimesh, list]], names: list[str], path,
                         up=None, per_row: int = 4, cell: tuple[int, int] = (300, 260)) -> Path:
    """One PNG, atomically: per cell (title, mesh, GCs in template order) the mesh in light grey
    and each GC in its template colour (`gc_color`), a legend of `names` in the first cell.
    `up`: per cell (3,) up vectors (None: +z), so each cell stands its shape upright."""
    from .camera import VIEW_ANGLE, frame_points, side_view

    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    n = max(len(cells), 1)
    cols = min(per_row, n)
    rows = (n + cols - 1) // cols
    p = pv.Plotter(off_screen=True, shape=(rows, cols), window_size=(cell[0] * cols, cell[1] * rows),
                   border=False)
    p.set_background("white")
    for k, (title, mesh, gcs) in enumerate(cells):
        p.subplot(k // cols, k % cols)
        p.add_text(title, position=(4, cell[1] - 16), font_size=6, color="black")
        p.add_mesh(pv.PolyData.from_regular_faces(np.asarray(mesh.vertices, float),
                                                  np.asarray(mesh.faces)), color="#dddddd",
                   opacity=0.35)
        pts = [np.asarray(mesh.vertices)]
        for g, gc in enumerate(gcs):
            s = gc_surface(gc, n_u=32, n_theta=16)
            pts.append(np.asarray(s.vertices))
            p.add_mesh(pv.PolyData.from_regular_faces(np.asarray(s.vertices, float),
                                                      np.asarray(s.faces)), color=gc_color(g),
                       opacity=0.8, smooth_shading=True)
        if k == 0:
            p.add_legend([[nm, gc_color(g)] for g, nm in enumerate(names)], bcolor="white",
                         size=(0.3, 0.45), loc="lower left", face="rectangle")
        u = np.asarray(up[k] if up is not None else (0.0, 0.0, 1.0), dtype=float)
        allp = np.concatenate(pts)
        d = side_view(allp, u)
        c, dist = frame_points(allp, d, u, aspect=cell[0] / cell[1], view_angle=VIEW_ANGLE,
                               fill=(0.9, 0.8))
        p.camera.view_angle = VIEW_ANGLE
        p.camera_position = [tuple(c + dist * d), tuple(c), tuple(u)]
        p.reset_camera_clipping_range()
    return save_screenshot(p, path)
