"""A missing leg of a pair stands in as its found partner's mirror image when that lies on the
mesh (a crocodile's pruned hind foot), and not when the mesh has nothing there; a missing
tail starts where the template starts it."""
from __future__ import annotations

import numpy as np

from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.tighten import gc_volume
from ngc_gen.data.autogc.transfer import BodyFrame, TransferSettings
from ngc_gen.data.autogc.transfer.assemble import Placing, _missing_gc, _straight
from ngc_gen.data.autogc.transfer.mirror import mirror_stand_in, mirrored_gc
from ngc_gen.data.mesh.sampling import sample_surface
from ngc_gen.geometry import GeneralizedCylinder

from ...helpers import ROOT
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


def test_a_missing_tail_starts_where_the_template_starts_it_not_at_the_torsos_end():
    """A torso's path runs between the limbs' junctions and may end at the hips, far in front
    of the rump (a rhino's, a giraffe's). The missing tail's stand-in starts where the template
    starts a tail, inside the rump, and reaches the stub behind it; started at the torso's end,
    the stub lay beyond the tail's reach and the stand-in was a small GC at the hips."""
    template = load_template(ROOT / "datasets/animals/quadruped_transfer.yaml")
    body = BodyFrame(np.eye(3), np.zeros(3), np.array([1.0, 0.4, 0.5]))   # front, left, up
    rump = tubes([((-0.9, 0.0, 0.0), (0.9, 0.0, 0.0))], [0.2])
    stub = tubes([((-0.9, 0.0, 0.0), (-1.0, 0.0, -0.02))], [0.03])
    surface = np.vstack([sample_surface(np.asarray(m.vertices), np.asarray(m.faces), n,
                                        np.random.default_rng(0))[0]
                         for m, n in ((rump, 4000), (stub, 400))])
    torso = _straight(template.gc("torso"), np.array([0.3, 0.0, 0.0]), np.array([-1.0, 0, 0]),
                      0.6, 0.2, np.array([0.0, 0.0, 1.0]))        # ends at x = -0.3: the hips
    pl = Placing(template, TransferSettings.from_yaml(), None, surface, None, body, np.eye(3), {},
                 None, ["tail"], 0.0, floor=1e-3, gcs={"torso": torso})
    _missing_gc(pl, "tail", body.to_body(surface))
    tail = pl.gcs["tail"]
    start = np.asarray(tail.to_world(np.array([[-1.0, 0.0, 0.0]])))[0]
    assert np.linalg.norm(body.to_body(start) - template.gc("tail").place["start"]) < 0.05
    tip = np.array([[-0.99, 0.0, -0.02]])
    assert rho_matrix([tail], tip)[0][0, 0] <= 1.0                # the stub is the tail's
