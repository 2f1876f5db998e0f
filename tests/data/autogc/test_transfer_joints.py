"""Where a neck meets its head on one skeleton path: at the poll, the waist between the neck's
thin top and the wider skull, not at the sharpest bend (a level skull's bend into its muzzle)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
from ngc_gen.data.autogc.transfer.chain_joints import bend_near, joint_near, waist_near
from ngc_gen.data.mesh.io import normalize

from ...helpers import ROOT
from .shapes import tubes

pytestmark = pytest.mark.usefixtures("single_thread")
FAST = TransferSettings.from_yaml(resolution=64, samples=5000, up="+y", front="+z")


def _level_headed(length=0.8, leg=0.7):
    """(mesh, points) y up, facing +z: a stick quadruped whose neck rises 40 degrees and thins
    to its top, a level skull wider than that top, and a muzzle bent 60 degrees down (the
    sharpest bend of the neck-and-head path is the skull's into the muzzle, as on a horse)."""
    y, z0, z1 = 0.1, -length / 2, length / 2
    feet = [(x, y - leg, z) for x in (0.14, -0.14) for z in (z1 - 0.05, z0 + 0.05)]
    base, up = np.array([0.0, y, z1]), np.array([0.0, np.sin(0.7), np.cos(0.7)])
    mid, poll = base + 0.25 * up, base + 0.5 * up
    brow = poll + np.array([0.0, 0.0, 0.2])
    nose = brow + 0.16 * np.array([0.0, -np.sin(np.pi / 3), np.cos(np.pi / 3)])
    segs = [((0, y, z0), (0, y, z1))] + [((f[0], y, f[2]), f) for f in feet] + [
        (base, mid), (mid, poll), (poll, brow), (brow, nose), ((0, y, z0), (0, y - 0.3, z0 - 0.25))]
    mesh = tubes(segs, [0.16, 0.06, 0.06, 0.06, 0.06, 0.09, 0.055, 0.085, 0.05, 0.035])
    m, center, scale = normalize(mesh)
    points = {"skull": (poll + brow) / 2, "throat": mid, "nose": nose}
    return m, {k: (v - center) * scale for k, v in points.items()}


def test_the_head_begins_at_the_poll_not_at_the_muzzles_bend():
    """The template's lengths put the neck-and-head joint near the poll, and the path bends
    there (40 degrees) and again where the muzzle drops (60): cut at the sharpest bend, the
    neck GC took the whole skull and the head only the muzzle. The skull is wider than the
    neck's top: the head begins at that waist and holds the skull; the neck keeps the throat."""
    mesh, pts = _level_headed()
    tr = transfer_template(mesh, load_template(ROOT / "datasets/animals/quadruped_transfer.yaml"),
                           dataclasses.replace(FAST), "level")
    by = {g.name: g for g in tr.gcs}
    assert tr.missing == []
    assert bool(by["head"].contains(pts["skull"][None])[0])
    assert not bool(by["neck"].contains(pts["skull"][None])[0])
    assert bool(by["head"].contains(pts["nose"][None])[0])
    assert bool(by["neck"].contains(pts["throat"][None])[0])


def test_a_path_without_a_waist_is_cut_at_its_bend():
    """A neck that thins into a narrower head has no waist: the joint stays at the sharpest
    bend near the template's share; with a wider skull after the thin top, at the waist."""
    s = np.linspace(0.0, 1.0, 41)
    P = np.stack([np.zeros_like(s), np.where(s < 0.6, s, 0.6), np.where(s < 0.6, 0.0, s - 0.6)], 1)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    tapering = np.linspace(0.1, 0.04, 41)
    assert waist_near(tapering, arc, 20) is None
    assert bend_near(P, arc, 20) == 24
    skull = tapering.copy()
    skull[18:26] = 0.09                                    # the skull from node 18 on
    assert waist_near(skull, arc, 20) == 17


def test_a_waist_past_where_the_templates_chain_ends_is_no_joint():
    """An elephant's path runs on past where the template's head ends, down its trunk, which
    thins with rings and the tusks' junction along it: those waists belong to the head, whose
    joint with the neck is looked for only up to the template's end (else at the bend)."""
    s = np.linspace(0.0, 1.0, 41)
    P = np.stack([np.zeros_like(s), s, np.zeros_like(s)], 1)
    arc = s.copy()
    trunk = np.linspace(0.25, 0.04, 41)
    trunk[30:33] = 0.12                                    # a ring around the trunk
    assert joint_near(P, trunk, arc, 26, end=40) == 29
    assert joint_near(P, trunk, arc, 26, end=27) == bend_near(P, arc, 26)
