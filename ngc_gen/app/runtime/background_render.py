"""A renderer that starts before the work does: a forked child imports pyvista and opens its
first off-screen OpenGL context (about 1.2 s on two cores, measured: import 0.46 s, first
plotter 0.78 s, later ones 0.04 s) while the parent loads the model and meshes it, then runs
the parent's render calls. A command that ends in one picture (`edit.py`) waits only for the
drawing itself.

Fork is used because the child must start at once from the parent as it is (a spawned child
would import the entry point and torch again); where fork is not available, or the child has
died, the call runs in the parent as it would without this module. It lives in the app layer,
not in `ngc_gen.viz`, so creating it imports nothing heavy; the child imports `ngc_gen.viz`.
"""
from __future__ import annotations

import logging
import multiprocessing as mp
import os

log = logging.getLogger(__name__)


def _warm_up() -> None:
    """Import what a render needs and draw once, off-screen, so the first real call is fast."""
    os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    import ngc_gen.viz.render  # noqa: F401  (what the calls run; pulls trimesh and torch too)

    p = pv.Plotter(off_screen=True, window_size=(16, 16))
    p.add_mesh(pv.Sphere())
    p.screenshot(return_img=True)
    p.close()


def _serve(conn) -> None:
    """The child: warm up, then answer (fn, args, kwargs) with ('ok', result) or
    ('error', message) until the parent sends None or goes away."""
    try:
        _warm_up()
    except Exception as e:  # noqa: BLE001  (reported with the first call)
        warm_error = f"{type(e).__name__}: {e}"
    else:
        warm_error = None
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        if warm_error is not None:
            conn.send(("error", warm_error))
            continue
        fn, args, kwargs = job
        try:
            conn.send(("ok", fn(*args, **kwargs)))
        except Exception as e:  # noqa: BLE001
            conn.send(("error", f"{type(e).__name__}: {e}"))


class BackgroundRenderer:
    """`with BackgroundRenderer() as r: ...; r.render(render_grid, path, rows, ...)`.

    `render(fn, path, *args, **kwargs)` is `render_or_warn`'s contract: the path written, or
    None with a warning when the picture could not be drawn (a picture is a convenience beside
    outputs already written). Arguments travel by pickle (trimesh meshes, numpy arrays)."""

    def __init__(self, enabled: bool = True):
        self._conn = self._proc = None
        if enabled and "fork" in mp.get_all_start_methods():
            ctx = mp.get_context("fork")
            self._conn, child = ctx.Pipe()
            self._proc = ctx.Process(target=_serve, args=(child,), daemon=True,
                                     name="ngc-renderer")
            self._proc.start()
            child.close()

    def render(self, fn, path, *args, **kwargs):
        from ngc_gen.viz.render import render_or_warn

        if self._proc is None or not self._proc.is_alive():
            return render_or_warn(fn, path, *args, **kwargs)
        try:
            self._conn.send((fn, (*args, path), kwargs))
            status, value = self._conn.recv()
        except (EOFError, OSError, BrokenPipeError):  # the child died: draw here instead
            self.close()
            return render_or_warn(fn, path, *args, **kwargs)
        if status == "error":
            log.warning("could not render %s: %s", path, value)
            return None
        return value

    def close(self) -> None:
        if self._proc is None:
            return
        try:
            self._conn.send(None)
        except (OSError, BrokenPipeError):
            pass
        self._proc.join(timeout=5)
        if self._proc.is_alive():
            self._proc.kill()
        self._conn.close()
        self._conn = self._proc = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
