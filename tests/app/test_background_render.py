"""The renderer that warms up in a forked child: the same picture as a render in the process,
failures reported as a warning (no exception), a dead child replaced by drawing here."""
import logging

import numpy as np
import pytest
import trimesh

from ngc_gen.app.runtime.background_render import BackgroundRenderer
from ngc_gen.viz import render_grid

pytest.importorskip("pyvista")


def _pixels(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def _failing_render(path, **kwargs):
    raise RuntimeError("no OpenGL here")


def test_child_draws_the_same_picture_as_the_parent(tmp_path):
    rows = [[trimesh.creation.icosphere(subdivisions=2), trimesh.creation.box()]]
    here = render_grid(rows, tmp_path / "here.png", cell=(120, 100))
    with BackgroundRenderer() as r:
        assert r._proc is not None and r._proc.is_alive()  # forked, not drawing in-process
        child_pid = r._proc.pid
        there = r.render(render_grid, tmp_path / "child.png", rows, cell=(120, 100))
        again = r.render(render_grid, tmp_path / "child2.png", rows[:1], cell=(120, 100))
    assert child_pid is not None and there == tmp_path / "child.png"
    assert again == tmp_path / "child2.png"
    a, b = _pixels(here), _pixels(there)
    assert a.shape == b.shape == (100, 240, 3)
    assert np.abs(a - b).max() <= 2  # the same scene, the same pixels
    assert (np.abs(b - 255).sum(-1) > 30).mean() > 0.05  # and something is drawn


def test_a_failed_render_is_a_warning_not_an_error(tmp_path, caplog):
    with BackgroundRenderer() as r, caplog.at_level(logging.WARNING):
        assert r.render(_failing_render, tmp_path / "x.png") is None
    assert "could not render" in caplog.text and "no OpenGL here" in caplog.text
    assert not (tmp_path / "x.png").exists()


def test_a_dead_child_is_replaced_by_drawing_here(tmp_path):
    rows = [[trimesh.creation.box()]]
    with BackgroundRenderer() as r:
        r._proc.kill()
        r._proc.join()
        out = r.render(render_grid, tmp_path / "here.png", rows, cell=(80, 80))
    assert out == tmp_path / "here.png" and out.exists()


def test_disabled_renderer_forks_nothing(tmp_path):
    with BackgroundRenderer(enabled=False) as r:
        assert r._proc is None
        out = r.render(render_grid, tmp_path / "p.png", [[trimesh.creation.box()]],
                       cell=(80, 80))
    assert out.exists()
