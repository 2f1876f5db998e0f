"""Pictures of a rigged shape: its rest pose with the joints drawn, and an animated GIF of
posed meshes (frames of a clip played back from the exported file)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .render import COLORS
from .screenshot import save_screenshot


def _plotter(size):
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    p = pv.Plotter(off_screen=True, window_size=size, border=False)
    p.set_background("white")
    return pv, p


def _camera(p, points: np.ndarray, up) -> None:
    from .camera import VIEW_ANGLE, frame_points, resolve_up, side_view

    u = resolve_up(up, [points])
    d = side_view(points, u)
    c, dist = frame_points(points, d, u, aspect=p.window_size[0] / p.window_size[1],
                           view_angle=VIEW_ANGLE, fill=(0.9, 0.9))
    p.camera.view_angle = VIEW_ANGLE
    p.camera_position = [tuple(c + dist * d), tuple(c), tuple(u)]
    p.reset_camera_clipping_range()


def render_rest_pose(vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray,
                     parent: np.ndarray, path, size=(640, 480), up="auto") -> Path:
    """The mesh translucent, each joint a dot and each bone a line to its parent (PNG)."""
    pv, p = _plotter(size)
    p.add_mesh(pv.PolyData.from_regular_faces(np.asarray(vertices, float), np.asarray(faces)),
               color=COLORS[0], opacity=0.35, smooth_shading=True)
    has = np.flatnonzero(parent >= 0)
    if len(has):
        p.add_lines(np.stack([joints[parent[has]], joints[has]], 1).reshape(-1, 3),
                    color="#203060", width=3)
    p.add_points(np.asarray(joints, float), color="#c03030", point_size=9,
                 render_points_as_spheres=True)
    _camera(p, np.asarray(vertices), up)
    return save_screenshot(p, path)


def render_animation(frames: list[np.ndarray], faces: np.ndarray, path, fps: float = 12.0,
                     size=(480, 360), up="auto") -> Path:
    """An animated GIF of posed vertex sets (each (V, 3), one mesh topology `faces`), one
    camera framing all frames."""
    from PIL import Image

    pv, p = _plotter(size)
    mesh = pv.PolyData.from_regular_faces(np.asarray(frames[0], float), np.asarray(faces))
    p.add_mesh(mesh, color=COLORS[0], smooth_shading=True)
    _camera(p, np.concatenate(frames), up)
    images = []
    for v in frames:  # frames (tens)
        mesh.points = np.asarray(v, float)
        mesh.compute_normals(inplace=True)
        p.render()
        images.append(Image.fromarray(p.screenshot(return_img=True)))
    p.close()
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp.gif")
    images[0].save(tmp, save_all=True, append_images=images[1:], loop=0,
                   duration=int(1000 / fps))
    os.replace(tmp, path)
    return path
