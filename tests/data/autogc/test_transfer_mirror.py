"""A missing leg of a pair stands in as its found partner's mirror image when that lies on the
mesh (a crocodile's pruned hind foot), and not when the mesh has nothing there."""
from __future__ import annotations

import numpy as np

from ngc_gen.data.autogc.tighten import gc_volume
from ngc_gen.data.autogc.transfer import BodyFrame
from ngc_gen.data.autogc.transfer.mirror import mirror_stand_in, mirrored_gc
from ngc_gen.data.mesh.sampling import sample_surface
from ngc_gen.geometry import GeneralizedCylinder

from .shapes import tubes

# the body frame: rows front, left, up = world z, x, y (y up, facing +z, as the animals)
BODY = BodyFrame(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
                 np.array([0.0, 0.0, 0.0]), np.array([0.6, 0.4, 0.5]))


def _leg(x: float, name: str) -> GeneralizedCylinder:
    a, b = np.array([x, 0.0, -0.3]), np.array([x, -0.45, -0.3])
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": np.linspace(a, b, 4).tolist()},
        "up": [0.0, 0.0, 1.0], "keys": [{"t": t, "radii": [0.07, 0.07], "twist": 0.0}
                                        for t in (0.0, 0.5, 1.0)], "caps": [0.03, 0.03]})


def _surface(*legs_x: float) -> np.ndarray:
    segs = [((0.0, 0.0, -0.5), (0.0, 0.0, 0.5))] + [((x, 0.0, -0.3), (x, -0.45, -0.3))
                                                     for x in legs_x]
    m = tubes(segs, [0.15] + [0.06] * len(legs_x))
    return sample_surface(np.asarray(m.vertices), np.asarray(m.faces), 4000,
                          np.random.default_rng(0))[0]


def test_the_mirror_image_lands_on_the_other_side_with_the_partners_shape():
    left = _leg(0.2, "leg_bl")
    m = mirrored_gc(left, BODY, "leg_br")
    assert m.name == "leg_br"
    line = np.stack([np.linspace(-1, 1, 5), np.zeros(5), np.zeros(5)], 1)
    a, b = np.asarray(left.to_world(line)), np.asarray(m.to_world(line))
    assert np.allclose(b[:, 0], -a[:, 0]) and np.allclose(b[:, 1:], a[:, 1:])
    assert np.isclose(gc_volume(m), gc_volume(left))


def test_a_missing_legs_stand_in_is_its_partners_mirror_only_where_the_mesh_has_that_leg():
    left = _leg(0.2, "leg_bl")
    pts = _surface(0.2, -0.2)                       # both hind legs
    m = mirror_stand_in(left, BODY, "leg_br", pts)
    assert m is not None
    foot = np.array([[-0.2, -0.4, -0.3]])            # on the right hind leg
    assert bool(m.contains(foot)[0])
    assert mirror_stand_in(left, BODY, "leg_br", _surface(0.2)) is None   # no right leg there
