"""The editor's mesh loop: a coarse preview after every change, a refined mesh once the
interaction ends (a released drag, or a slider left alone for `delay` seconds).

One worker thread extracts meshes of the session's latest document only (changes that arrive
during an extraction are coalesced), so the GUI threads never wait for the network.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Shown:
    """A mesh the scene shows: document version, grid resolution, faces, seconds extracting,
    and when it reached the scene (time.perf_counter)."""

    version: int
    resolution: int
    n_faces: int
    seconds: float
    at: float


class MeshLoop:
    """session: an EditorSession; show(version, resolution, result, seconds) puts a mesh into
    the scene; on_error(message) reports a failed extraction; preview_kw / refine_kw: extraction
    settings of each pass (`EditorSession.mesh`)."""

    def __init__(self, session, preview: int, refine: int, delay: float,
                 show: Callable, on_error: Callable[[str], None],
                 preview_kw: dict | None = None, refine_kw: dict | None = None):
        self.session, self.preview, self.refine = session, int(preview), int(refine)
        self.extract_kw = {self.preview: dict(preview_kw or {}),
                           self.refine: dict(refine_kw or {})}
        self.delay = float(delay)
        self._show, self._on_error = show, on_error
        self._cond = threading.Condition()
        self._changed_at = float("-inf")   # start refined at once
        self._stop = False
        self.shown = Shown(-1, 0, 0, 0.0, 0.0)
        self._thread = threading.Thread(target=self._run, name="editor-mesh", daemon=True)

    def start(self) -> "MeshLoop":
        self._thread.start()
        return self

    def stop(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join(timeout=30)

    def changed(self, released: bool = False) -> None:
        """The document changed (or, released: the interaction ended; refine now)."""
        with self._cond:
            self._changed_at = float("-inf") if released else time.perf_counter()
            self._cond.notify_all()

    def released(self) -> None:
        self.changed(released=True)

    def _next(self) -> tuple[int, int, object] | None:
        """(version, resolution, shape) to extract next, or None when the scene is current;
        also the seconds to wait before the refine is due."""
        version, shape = self.session.snapshot()
        if self.shown.version < version and self.preview < self.refine:
            return version, self.preview, shape
        if (self.shown.version, self.shown.resolution) != (version, self.refine):
            wait = self._changed_at + self.delay - time.perf_counter()
            if wait <= 0:
                return version, self.refine, shape
            return None, wait, None
        return None

    def _run(self) -> None:
        while True:
            with self._cond:
                while True:
                    if self._stop:
                        return
                    job = self._next()
                    if job is not None and job[0] is not None:
                        break
                    self._cond.wait(timeout=None if job is None else job[1])
            version, resolution, shape = job
            t0 = time.perf_counter()
            try:
                result = self.session.mesh(resolution, shape=shape, version=version,
                                           **self.extract_kw[resolution])
                seconds = time.perf_counter() - t0
                self._show(version, resolution, result, seconds)
            except Exception as e:  # the loop must outlive a bad extraction
                self._on_error(f"mesh extraction failed ({type(e).__name__}: {e})")
                seconds = time.perf_counter() - t0
                result = None
            with self._cond:
                n = 0 if result is None else len(result.mesh.faces)
                self.shown = Shown(version, resolution, n, seconds, time.perf_counter())
                self._cond.notify_all()

    def wait_for(self, version: int, resolution: int, timeout: float = 60.0) -> Shown:
        """Block until the scene shows document `version` (or a later one) at `resolution`."""
        end = time.perf_counter() + timeout
        with self._cond:
            while not (self.shown.version >= version and self.shown.resolution == resolution):
                left = end - time.perf_counter()
                if left <= 0:
                    raise TimeoutError(f"no mesh of version {version} at {resolution}^3 within "
                                       f"{timeout} s (showing {self.shown})")
                self._cond.wait(timeout=left)
            return self.shown
