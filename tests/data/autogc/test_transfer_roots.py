"""Where a leg's own surface begins: the flank over its hip joint is the leg's, as a rig's leg
moves it, though the skeleton's leg branch leaves the body only at the belly line."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix

from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import BodyFrame, Tree
from ngc_gen.data.autogc.transfer.roots import joint_columns, owner_of

from ...helpers import ROOT

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"


def _line(a, b, n):
    return np.linspace(a, b, n)


def _hip_scene():
    """A body-frame-aligned tree (world x front, y left, z up): a torso path along x at
    z = 0.1 (thick), and the back-left leg's path from its junction on it diagonally down and
    out to the belly line, then down to the foot; the diagonal's upper half inside the body is
    the torso's (as ``match._labels`` trims a limb's first nodes), the rest the leg's."""
    torso = _line([-0.9, 0, 0.1], [0.7, 0, 0.1], 33)
    diag = _line([-0.6, 0, 0.1], [-0.6, 0.25, -0.35], 10)[1:]
    shin = _line([-0.6, 0.25, -0.35], [-0.6, 0.25, -0.6], 6)[1:]
    nodes = np.concatenate([torso, diag, shin])
    radius = np.r_[np.full(33, 0.45), np.linspace(0.4, 0.1, 9), np.full(5, 0.08)]
    j = int(np.argmin(np.linalg.norm(torso - [-0.6, 0, 0.1], axis=1)))
    chain = [j, *range(33, len(nodes))]
    edges = [(i, i + 1) for i in range(32)] + list(zip(chain[:-1], chain[1:]))
    E = np.asarray(edges)
    w = np.linalg.norm(nodes[E[:, 0]] - nodes[E[:, 1]], axis=1)
    G = coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                   shape=(len(nodes),) * 2).tocsr()
    n = len(nodes)
    tree = Tree(nodes, radius, G, np.ones(n, bool), np.zeros(n, int), np.zeros((1, 3)),
                np.ones(1), np.zeros((1, 3)))
    template = load_template(TEMPLATE)
    torso_i, leg_i = template.names.index("torso"), template.names.index("leg_bl")
    labels = np.full(n, torso_i)
    leg_path = chain[5:]                      # the diagonal's lower half and the shin
    labels[leg_path] = leg_i
    body = BodyFrame(np.eye(3), np.zeros(3), np.array([1.0, 0.5, 0.6]))
    return template, tree, labels, body, {"torso": list(range(33)), "leg_bl": leg_path}


def test_the_flank_over_a_legs_hip_is_the_legs_not_the_torsos():
    """Without the column up to the hip, the flank above where the leg's branch leaves the
    body is nearest the torso's path (or the trimmed top of the leg's own branch) and is the
    torso's: the leg's GC then holds barely half of what a rig's leg moves."""
    template, tree, labels, body, paths = _hip_scene()
    names = template.names
    flank = np.array([-0.6, 0.45, 0.1])           # over the left hip, at its joint
    samples = np.array([flank,
                        [-0.6, -0.45, 0.05],      # the other side's flank: no right leg here
                        [-0.6, 0.0, 0.55],        # the back's top over the hip
                        [0.3, 0.45, 0.05],        # the flank far in front of the hip
                        [-0.6, 0.3, -0.5]])       # the leg itself
    near = labels[np.argmin(np.linalg.norm(samples[:, None] - tree.nodes[None], axis=2), 1)]
    assert names[near[0]] == "torso"               # what the nearest node alone gives
    got = [names[g] for g in owner_of(samples, template, tree, labels, body, paths)]
    assert got == ["leg_bl", "torso", "torso", "torso", "leg_bl"]


def test_a_legs_column_runs_from_where_it_is_thin_up_to_its_joints_height():
    template, tree, labels, body, paths = _hip_scene()
    pts, lab = joint_columns(template, tree, body, paths)
    assert len(pts) and set(lab) == {template.names.index("leg_bl")}
    start = body.to_world(np.asarray(template.gc("leg_bl").place["start"]))
    assert pts[:, 2].max() == pytest.approx(start[2])          # up to the joint's height
    assert pts[:, 2].min() > -0.35                            # above where the leg is thin
    assert np.allclose(pts[:, :2], [-0.6, 0.25])              # at the leg's own place
    # a leg whose thin part begins above its joint's height has no column
    body_low = BodyFrame(np.eye(3), np.array([0.0, 0.0, -0.9]), np.array([1.0, 0.5, 0.6]))
    assert len(joint_columns(template, tree, body_low, paths)[0]) == 0


def test_a_legs_column_takes_only_its_parents_surface():
    """The tail's root beside the hip stays the tail's: the leg takes the torso's flank only."""
    template, tree, labels, body, paths = _hip_scene()
    names = template.names
    tail_root = np.array([[-0.6, 0.45, 0.1]])
    labels = labels.copy()
    near = int(np.argmin(np.linalg.norm(tree.nodes - tail_root, axis=1)))
    labels[near] = names.index("tail")
    got = owner_of(tail_root, template, tree, labels, body, paths)
    assert names[got[0]] == "tail"
