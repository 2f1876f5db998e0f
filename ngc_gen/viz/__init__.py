"""Pictures: off-screen renders of meshes and GC surfaces (pyvista), and their cameras."""
from .camera import detect_up, least_motion_view, resolve_up, side_view, up_vector
from .gc_mesh import gc_labels, gc_surface, gcs_surface
from .render import render_gallery, render_grid, render_or_warn

__all__ = ["detect_up", "gc_labels", "gc_surface", "gcs_surface", "least_motion_view",
           "render_gallery", "render_grid", "render_or_warn", "resolve_up", "side_view",
           "up_vector"]
