"""Pictures: off-screen renders of meshes and GC surfaces (pyvista)."""
from .gc_mesh import gc_surface, gcs_surface
from .render import render_gallery, render_grid, render_or_warn

__all__ = ["gc_surface", "gcs_surface", "render_gallery", "render_grid", "render_or_warn"]
