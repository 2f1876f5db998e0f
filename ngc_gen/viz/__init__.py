"""Pictures: off-screen renders of meshes (pyvista)."""
from .render import render_grid

__all__ = ["render_grid"]
