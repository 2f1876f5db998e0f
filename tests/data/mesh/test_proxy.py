"""The closed proxy of a mesh wound inward (0 A.D.'s game meshes wind their faces clockwise) or
of pieces that disagree is the solid the surface encloses, not a hollow slab around it."""
from __future__ import annotations

import numpy as np
import trimesh

from ngc_gen.data.mesh.proxy import closed_proxy, outward_faces


def _inside_share(V, F) -> float:
    proxy = closed_proxy(V, F, resolution=32)
    assert len(proxy.components) == 1  # one closed surface: no inner shell
    return float(abs(proxy.components[0].volume))


def test_a_mesh_wound_inward_gives_the_same_solid_proxy():
    box = trimesh.creation.box((2.0, 1.0, 1.0))
    V, F = np.asarray(box.vertices), np.asarray(box.faces)
    solid = _inside_share(V, F)
    assert np.isclose(_inside_share(V, F[:, ::-1]), solid, rtol=1e-6)
    assert solid > 0.9 * 2.0  # the box's volume (the proxy is offset outward a little)


def test_each_piece_is_turned_outward_on_its_own():
    a = trimesh.creation.box((1.0, 1.0, 1.0))
    b = trimesh.creation.icosphere(2, 0.4)
    b.apply_translation((2.0, 0.0, 0.0))
    V = np.concatenate([a.vertices, b.vertices])
    F = np.concatenate([a.faces[:, ::-1], b.faces + len(a.vertices)])  # the box inward
    out = outward_faces(V, F)
    n = len(a.faces)
    assert np.array_equal(out[:n], a.faces) and np.array_equal(out[n:], F[n:])
    # a piece split at seams (its vertices duplicated) is still one piece
    seam = np.asarray(a.vertices)[np.asarray(a.faces)].reshape(-1, 3)
    split = np.arange(len(seam)).reshape(-1, 3)[:, ::-1]
    assert trimesh.Trimesh(seam, outward_faces(seam, split), process=False).volume > 0.99
