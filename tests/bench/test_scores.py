"""The transfer benches' purity: a sample belongs to the rig GC the skin gives it where the truth
keeps the skin's split, not to whichever true GC is relatively nearest."""
from __future__ import annotations

import numpy as np

from bench._scores import skin_parts, truth_purity
from ngc_gen.geometry import GeneralizedCylinder


def _gc(name, a, b, r, up=(0.0, 0.0, 1.0)):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": [a, b]}, "up": list(up),
        "keys": [{"t": 0.0, "radii": [r, r]}], "caps": [r, r]})


def test_the_skins_split_decides_which_truth_part_a_sample_is(tmp_path):
    # a thin true head along x beside a fat true torso; the points hang below the head (a
    # trunk): the skin says head, while the relatively nearest true GC is the torso
    truth = [_gc("torso", [-3.0, 0.0, 0.0], [-1.5, 0.0, 0.0], 1.0),
             _gc("head", [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1)]
    V = np.stack([np.full(50, 0.1), np.zeros(50), -np.linspace(0.3, 1.2, 50)], 1)
    owner = tmp_path / "m.owner.npz"
    np.savez(owner, names=np.array(["head", "antler", "torso"]), owner=np.zeros(50, np.int16))
    part = skin_parts(owner, V, V + 1e-3, ["torso", "head"])
    assert (part == 1).all()
    ours = [_gc("torso", [-3.0, 0.0, 0.0], [-1.5, 0.0, 0.0], 1.0),
            _gc("head", [0.1, 0.0, 0.0], [0.1, 0.0, -1.3], 0.2, up=(1.0, 0.0, 0.0))]
    np.testing.assert_allclose(truth_purity(truth, ours, V, part), [np.nan, 1.0])
    # by the nearest true GC the trunk is the torso's, and a head that holds it scores nothing
    np.testing.assert_allclose(truth_purity(truth, ours, V), [0.0, np.nan])
