"""Pictures: off-screen renders of meshes and GC surfaces (pyvista)."""
from .gc_mesh import gc_surface, gcs_surface
from .render import render_grid

__all__ = ["gc_surface", "gcs_surface", "render_grid"]
