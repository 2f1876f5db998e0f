"""Editor fixtures: the edit tests' tube-weight checkpoint (two shapes 'one', 'two' of three GCs
body, arm, tail; a real NGCDecoder, no fitting) opened in an editor session."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from ngc_gen.app.editor.library import ShapeLibrary
from ngc_gen.app.editor.session import EditorSession
from ngc_gen.app.editor.start import open_session
from ngc_gen.eval.fitting import chamfer

from ...edit.conftest import make_module, save_checkpoint
from ...helpers import compose_config

RES = 40  # small grids keep the replay tests fast; same grid on both sides


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    path = tmp_path_factory.mktemp("run") / "checkpoints" / "last.ckpt"
    path.parent.mkdir(parents=True)
    save_checkpoint(make_module(), path)
    return path


def editor_config(checkpoint, *overrides):
    return compose_config("edit", [f"run={checkpoint}", "viewer=true", *overrides])


@pytest.fixture(scope="module")
def opened(checkpoint):
    """One session opened from the real config per module (composing and loading are the slow
    part); tests get fresh copies."""
    return open_session(editor_config(checkpoint, "shape=one"))[0]


@pytest.fixture
def session(opened):
    """A fresh session on shape 'one' (its own library, so added shapes stay in the test)."""
    library = ShapeLibrary(dict(opened.library.shapes), opened.library.checkpoint)
    return EditorSession(library, "one", opened.limits, pose_at=opened.pose_at,
                         chunk=opened.chunk, name=opened.name)


def mesh_chamfer(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    """Chamfer (squared distances, mean each way, summed) between two meshes' vertices."""
    return chamfer(np.asarray(a.vertices, dtype=np.float64),
                   np.asarray(b.vertices, dtype=np.float64))
