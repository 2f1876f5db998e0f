"""A missing tail stands in over the surface behind the rump that the torso and legs leave
unexplained (a stub along the back's line, a tail hanging down the rump), not toward where the
template puts a tail's end; a tailless rear keeps the template's small stand-in."""
from __future__ import annotations

import numpy as np
import pytest

from ngc_gen.data.autogc.coverage import rho_matrix
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import BodyFrame, TransferSettings
from ngc_gen.data.autogc.transfer.assemble import Placing, _missing_gc
from ngc_gen.data.autogc.transfer.stray import stray_stand_in
from ngc_gen.data.mesh.sampling import sample_surface

from ...helpers import ROOT
from .shapes import tubes

BODY = BodyFrame(np.eye(3), np.zeros(3), np.array([1.0, 0.4, 0.5]))   # front, left, up
TORSO = ((-0.8, 0.0, 0.0), (0.8, 0.0, 0.0))
HIND = [((-0.6, y, -0.1), (-0.6, y, -0.5)) for y in (0.12, -0.12)]
FRONT = [((0.6, y, -0.1), (0.6, y, -0.5)) for y in (0.12, -0.12)]
STUB = ((-0.9, 0.0, 0.12), (-1.12, 0.0, 0.2))      # along the back's line, at its top
HANGING = ((-0.98, 0.0, 0.02), (-1.02, 0.0, -0.42))  # down behind the rump
PAWS = [((-0.6, y, -0.5), (-0.78, y / 2, -0.5)) for y in (0.12, -0.12)]  # back, on the ground


@pytest.fixture(scope="module")
def template():
    return load_template(ROOT / "datasets/animals/quadruped_transfer.yaml")


def _samples(seg, r, n):
    m = tubes([seg], [r])
    return sample_surface(np.asarray(m.vertices), np.asarray(m.faces), n,
                          np.random.default_rng(0))[0]


def _placing(template, tail=None, paws=False):
    """The torso and four legs found (fitted to their own samples as the transfer fits them),
    the tail missing; `tail` (a segment): the mesh has that tail; `paws`: hind paws reaching
    back toward the mid-plane on the ground, which the leg GCs leave out."""
    parts = {"torso": (TORSO, 0.2, 3000)}
    parts.update({n: (s, 0.06, 600) for n, s in zip(("leg_bl", "leg_br"), HIND)})
    parts.update({n: (s, 0.06, 600) for n, s in zip(("leg_fl", "leg_fr"), FRONT)})
    own = {n: _samples(s, r, k) for n, (s, r, k) in parts.items()}
    extra = ([_samples(tail, 0.04, 400)] if tail else []) + \
        ([_samples(p, 0.045, 300) for p in PAWS] if paws else [])
    surface = np.vstack(list(own.values()) + extra)
    pl = Placing(template, TransferSettings.from_yaml(), None, surface, None, BODY, np.eye(3),
                 {}, None, ["tail"], 0.0, floor=1e-3)
    for n, (seg, _, _) in parts.items():
        poly = np.linspace(*(np.asarray(p) for p in seg), 16)
        pl.gcs[n] = pl.gc(template.gc(n), poly, own[n])
    return pl


@pytest.mark.parametrize("tail", [STUB, HANGING], ids=["stub along the back", "hanging"])
def test_a_missing_tail_stands_in_over_the_surface_the_body_leaves_unexplained(template, tail):
    """The template's tail ends low behind the rump; this tail lies elsewhere (along the back's
    line, or hanging down). Its stand-in holds the tail to its tip, and neither the torso's
    middle nor a hind foot."""
    pl = _placing(template, tail)
    _missing_gc(pl, "tail", BODY.to_body(pl.surface))
    gc = pl.gcs["tail"]
    on_tail = np.linspace(*(np.asarray(p) for p in tail), 5)
    assert (rho_matrix([gc], on_tail)[0][0] <= 1.0).all()
    assert not gc.contains(np.array([[0.0, 0.0, 0.0], [-0.6, 0.12, -0.5]])).any()


@pytest.mark.parametrize("paws", [False, True], ids=["legs", "paws reaching back"])
def test_a_tailless_rear_keeps_the_small_stand_in_at_its_attachment(template, paws):
    """Behind a tailless rump the torso and legs explain every sample above the feet (paws on
    the ground the leg GCs leave out are no tail): no tail grows over the rump, the thighs or
    the feet (the template's stand-in stays)."""
    pl = _placing(template, paws=paws)
    assert stray_stand_in(pl, template.gc("tail"), np.array([-0.66, 0.0, 0.15]),
                          BODY.to_body(pl.surface)) is None
    _missing_gc(pl, "tail", BODY.to_body(pl.surface))
    gc = pl.gcs["tail"]
    thighs = np.vstack([_samples(s, 0.06, 300) for s in HIND])
    assert not gc.contains(thighs).any()
    assert not gc.contains(np.array([p[1] for p in PAWS])).any()
