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


def _box_with_card():
    """A box and, inside it, a flat two-triangle card (a piece that encloses no volume, as a
    game model's fringes and decals are), tilted off the grid."""
    box = trimesh.creation.box((2.0, 1.0, 1.0))
    card = np.array([[-0.6, -0.3, -0.25], [0.6, -0.3, -0.15], [0.6, 0.3, 0.15], [-0.6, 0.3, 0.05]])
    V = np.concatenate([box.vertices, card])
    n = len(box.vertices)
    F = np.concatenate([box.faces, np.array([[0, 1, 2], [0, 2, 3]]) + n])
    return V, F, len(box.faces), np.asarray(box.faces)


def test_a_flat_piece_gives_the_same_proxy_whichever_way_the_input_is_wound():
    V, F, n_box, box_faces = _box_with_card()
    # the card's volume is rounding noise: its way must not follow the file's winding
    assert np.array_equal(outward_faces(V, F[:, ::-1]), outward_faces(V, F))
    a, b = closed_proxy(V, F, resolution=32), closed_proxy(V, F[:, ::-1], resolution=32)
    assert np.array_equal(a.inside, b.inside) and a.inside.sum() > 0.9 * 2.0 / a.h ** 3
    assert len(a.components) == len(b.components) == 1  # the card carves no cavity
    assert np.array_equal(a.components[0].vertices, b.components[0].vertices)
    assert np.array_equal(outward_faces(V, F)[:n_box], box_faces)  # the box stays outward
