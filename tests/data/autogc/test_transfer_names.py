"""Right names on real collections: a spur inside the hip is no tail, a chain that runs on past
where the template's head ends (a trunk) is cut where the template's part ends, and a frame is
levelled on the feet its match found."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.spatial.transform import Rotation

from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.autogc.transfer import BodyFrame, Tree, match_cost
from ngc_gen.data.autogc.transfer import match as match_module
from ngc_gen.data.autogc.transfer.match import _template_end, branch_lengths
from ngc_gen.data.autogc.transfer.orientation import LEVEL_DEG, ground_up

from ...helpers import ROOT

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
BODY = BodyFrame(np.eye(3), np.zeros(3), np.ones(3))   # world = body coordinates


@pytest.fixture(scope="module")
def template():
    return load_template(TEMPLATE)


def _tree(branches: list[np.ndarray]) -> Tree:
    """A tree of end branches, each (P, 3) from its root on the body to its free end."""
    nodes = np.vstack(branches)
    branch_of = np.concatenate([np.full(len(b), i) for i, b in enumerate(branches)])
    rows, cols, w = [], [], []
    start = 0
    for b in branches:
        ix = np.arange(start, start + len(b))
        d = np.linalg.norm(np.diff(b, axis=0), axis=1)
        rows += [*ix[:-1], *ix[1:]]
        cols += [*ix[1:], *ix[:-1]]
        w += [*d, *d]
        start += len(b)
    graph = csr_matrix((w, (rows, cols)), shape=(len(nodes), len(nodes)))
    tips = np.array([b[-1] for b in branches])
    roots = np.array([b[0] for b in branches])
    dirs = (tips - roots) / np.linalg.norm(tips - roots, axis=1, keepdims=True)
    radius = np.full(len(nodes), 0.02)
    radius[0] = 0.2                                    # the body's thickest part
    return Tree(nodes=nodes, radius=radius, graph=graph, main=np.ones(len(nodes), bool),
                branch_of=branch_of, branch_dir=dirs, branch_r=np.full(len(branches), 0.02),
                branch_root=roots)


def test_branch_lengths_are_the_arc_length_of_each_branch():
    tree = _tree([np.array([[0, 0, 0], [0, 0, 0.1]]),
                  np.array([[1, 0, 0], [1, 0.3, 0], [1, 0.3, 0.4]])])
    assert np.allclose(branch_lengths(tree), [0.1, 0.7])


def test_a_spur_inside_the_hip_is_no_tail_within_the_tails_reach(template, monkeypatch):
    """A lion's thin tail stands up and back, far from the template's hanging tail, so the
    first pass leaves it; within the tail's reach (the second pass) a spur of the skeleton
    inside the hip pointing down reads as a tail as well as the tail itself does. The spur is
    a quarter of a tail's length: it costs more, and the tail takes the real one. Without the
    length term the spur wins (the test can fail)."""
    spur = np.array([[-0.68, 0.1, 0.2], [-0.73, 0.1, 0.11]])
    tail = np.linspace([-0.68, 0.1, 0.35], [-1.0, 0.28, 0.75], 6)   # both leave the hip
    tree = _tree([np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.31]]), spur, tail])
    leaves = np.array([3, len(tree.nodes) - 1])                  # the spur's end, the tail's
    C = match_cost(template, tree, BODY, ["tail"], leaves, reach=True)[0]
    assert C[1] < C[0]
    monkeypatch.setattr(match_module, "W_SHORT", 0.0)
    C0 = match_cost(template, tree, BODY, ["tail"], leaves, reach=True)[0]
    assert C0[0] < C0[1]
    # the first pass does not weigh lengths: a posed limb's branch may be cut by an ear's
    assert np.allclose(match_cost(template, tree, BODY, ["tail"], leaves),
                       match_cost(template, tree, BODY, ["tail"], leaves))


def test_a_chain_running_on_past_where_the_templates_head_ends_is_cut_there(template):
    """An elephant's neck-and-head path runs over the skull, near where the template's head
    ends, then down the trunk: the template's head ends at the node nearest that place, and
    the chain is split by the template's lengths up to there (the trunk is the head's). A
    path whose tip is where the template's head ends (a horse's, a camel's) ends at its tip,
    and a grazing head far from it too."""
    end = np.asarray(template.gc("head").place["end"])
    skull = np.linspace([0.3, 0.0, 0.45], end + [-0.08, 0.0, 0.02], 8)
    trunk = np.linspace(end + [-0.05, 0.0, -0.1], [0.8, 0.0, -0.9], 12)
    nodes = np.vstack([skull, trunk])
    path = list(range(len(nodes)))
    assert _template_end(path, nodes, BODY, template.gc("head").place) == len(skull) - 1
    horse = np.linspace([0.3, 0.0, 0.2], end, 10)
    assert _template_end(list(range(10)), horse, BODY, template.gc("head").place) == 9
    grazing = np.linspace([0.3, 0.0, 0.2], [0.7, 0.0, -0.9], 10)
    assert _template_end(list(range(10)), grazing, BODY, template.gc("head").place) == 9


def test_feet_on_a_tilted_plane_give_the_ground(template):
    """Four feet on one plane tilted 30 degrees from the frame's up: its normal is the ground's
    up (on up's side). Feet on no plane (a leg raised in a gallop), a plane hardly tilted or
    tilted past LEVEL_DEG, fewer than four feet: no levelling."""
    feet = np.array([[0.5, 0.4, -1.0], [0.5, -0.4, -1.0], [-0.5, 0.4, -1.0], [-0.5, -0.4, -1.0]])
    up = np.array([0.0, 0.0, 1.0])
    R = Rotation.from_rotvec(np.radians(30.0) * np.array([0.0, 1.0, 0.0])).as_matrix()
    n = ground_up(feet @ R.T, up)
    assert n is not None and np.allclose(n, R @ up, atol=1e-9)
    assert np.allclose(ground_up(feet @ R.T, -up), -(R @ up), atol=1e-9)
    raised = feet.copy()
    raised[0, 2] += 0.6
    assert ground_up(raised @ R.T, up) is None
    assert ground_up(feet, up) is None                              # level already
    steep = Rotation.from_rotvec(np.radians(LEVEL_DEG[1] + 10.0) * np.array([0, 1.0, 0]))
    steep = steep.as_matrix()
    assert ground_up(feet @ steep.T, up) is None
    assert ground_up(feet[:3] @ R.T, up) is None


def test_a_leg_whose_end_lies_across_the_middle_is_missing_not_named_on_the_other_side(template):
    """A donkey's front feet touch, so its skeleton has no free end for them; the left front leg
    took a spur under the right shoulder. A limb of a symmetric pair whose end lies more than
    SIDE_SLACK across the mid-plane is left out (missing: a stand-in on its own side), a limb
    on its side or a part on the mid-plane (a tail swung aside) stays."""
    nodes = np.array([[0.3, -0.1, -0.2], [0.3, 0.45, -0.9], [-0.9, 0.3, -0.2], [-0.3, -0.02, -0.9]])
    tree = Tree(nodes=nodes, radius=np.full(4, 0.1), graph=None, main=np.ones(4, bool),
                branch_of=np.arange(4), branch_dir=np.tile([0, 0, -1.0], (4, 1)),
                branch_r=np.full(4, 0.05), branch_root=nodes)
    got = match_module._on_sides(template, tree, BODY,
                                 {"leg_fl": 0, "leg_fr": 1, "tail": 2, "leg_bl": 3})
    assert got == {"tail": 2, "leg_bl": 3}    # leg_fr's end lies left: out too; leg_bl: within


def test_an_ear_beside_a_short_neck_is_no_head_the_trunk_in_front_is(template, monkeypatch):
    """An elephant's skeleton has no free end where the template's head ends: its trunk hangs
    down in front, a thin branch, and an ear stands out beside the short neck, a thick plate.
    Within the head's reach (the second pass) the ear reads as a head better (its thickness);
    but a head's free end lies in front of where its neck starts, as a leg's lies below its
    hip: the ear, behind that, is out, and the trunk is the head's. A head lowered to graze
    stays within reach. Without the rule the ear wins (the test can fail)."""
    ear = np.linspace([0.1, 0.0, 0.4], [0.11, 0.59, 0.39], 5)
    trunk = np.linspace([0.5, 0.0, 0.5], [0.6, 0.05, -0.8], 8)
    tree = _tree([np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.31]]), ear, trunk])
    tree.branch_r[:] = [0.2, 0.1, 0.03]                   # a plate of an ear, a thin trunk
    leaves = np.array([len(ear) + 1, len(tree.nodes) - 1])   # the ear's end, the trunk's
    C = match_cost(template, tree, BODY, ["head"], leaves, reach=True)[0]
    assert C[1] < C[0]
    assert C[1] < 6.0                                     # within reach (annotate.missing_cost)
    monkeypatch.setattr(match_module, "_behind", lambda *a: np.zeros(len(a[-1]), bool))
    C0 = match_cost(template, tree, BODY, ["head"], leaves, reach=True)[0]
    assert C0[0] < C0[1]
    monkeypatch.undo()
    # the same rule at the other end: a tail's free end lies behind where the tail starts
    tips = np.array([[-0.9, 0.0, 0.0], [-0.5, 0.0, -0.3]])
    assert list(match_module._behind(template, "tail", np.asarray(
        template.gc("tail").place["end"]), tips)) == [False, True]
    grazing = np.array([[0.7, 0.0, -0.9]])
    assert not match_module._behind(template, "neck", np.asarray(
        template.gc("head").place["end"]), grazing).any()


def _joined(chain: np.ndarray, sides: list[tuple[int, np.ndarray]]) -> Tree:
    """A tree of one path `chain` (P, 3) and side branches (Q, 3), each leaving it at node j."""
    nodes = np.vstack([chain, *[b for _, b in sides]])
    edges = [(i, i + 1) for i in range(len(chain) - 1)]
    start = len(chain)
    for j, b in sides:
        edges += [(j, start)] + [(start + i, start + i + 1) for i in range(len(b) - 1)]
        start += len(b)
    e = np.asarray(edges)
    w = np.linalg.norm(nodes[e[:, 0]] - nodes[e[:, 1]], axis=1)
    graph = csr_matrix((np.r_[w, w], (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                       shape=(len(nodes), len(nodes)))
    n = len(nodes)
    return Tree(nodes=nodes, radius=np.full(n, 0.05), graph=graph, main=np.ones(n, bool),
                branch_of=np.zeros(n, int), branch_dir=np.zeros((1, 3)),
                branch_r=np.full(1, 0.05), branch_root=nodes[:1])


def test_a_head_starts_where_its_ears_leave_a_short_neck(template, monkeypatch):
    """A rhino's neck is short and its head long: the template's lengths cut its neck-and-head
    path far past its ears, and the neck GC takes the skull. Ears stand out of the head in a
    mirrored pair: the head starts just before where they leave the path. One side branch
    alone, or a pair behind where the neck starts (shoulder spurs), moves nothing. Without
    the rule the cut stays past the ears (the test can fail)."""
    chain = np.vstack([np.linspace([0.15, 0.0, 0.2], [0.38, 0.0, 0.27], 16)[:-1],
                       np.linspace([0.38, 0.0, 0.27], [0.69, 0.0, -0.21], 25)[:-1],
                       np.linspace([0.69, 0.0, -0.21], [0.97, 0.0, 0.09], 20)])
    j = 15                                                    # the ears' junction
    ears = [(j, np.linspace([0.45, 0.1, 0.35], [0.56, 0.5, 0.54], 5)),
            (j, np.linspace([0.45, -0.1, 0.35], [0.55, -0.5, 0.53], 5))]
    own = list(range(len(chain)))
    cut = match_module._chain_cuts(template, _joined(chain, ears), BODY, own, ["neck", "head"])
    assert cut[1] == j - 1 and cut[0] == 0 and cut[-1] == len(chain) - 1
    monkeypatch.setattr(match_module, "paired_junction", lambda *a: None)
    late = match_module._chain_cuts(template, _joined(chain, ears), BODY, own, ["neck", "head"])
    assert late[1] > j + 10
    monkeypatch.undo()
    one = match_module._chain_cuts(template, _joined(chain, ears[:1]), BODY, own, ["neck", "head"])
    assert one == late
    spurs = [(3, np.linspace([0.2, 0.1, 0.1], [0.25, 0.5, -0.2], 5)),
             (3, np.linspace([0.2, -0.1, 0.1], [0.25, -0.5, -0.2], 5))]
    behind = match_module._chain_cuts(template, _joined(chain, spurs), BODY, own, ["neck", "head"])
    assert behind == late


def test_a_spur_out_of_one_hip_is_no_tail_the_thin_one_on_the_mid_plane_is(template):
    """A giraffe calf's rump holds two free ends behind the hips: its thin tail, hanging on
    the mid-plane, and a thicker spur out of the right hip. A tail leaves the body on the
    mid-plane (only a head, on its neck's joints, turns its side away), so the spur's side
    costs what a leg's does and the tail takes the thin end. With the side weighed at half (as
    for a head) the thicker spur won: the calf was written with its tail on a hip."""
    tail = np.linspace([-0.81, 0.17, -0.28], [-0.86, 0.0, -0.49], 6)
    spur = np.linspace([-0.69, -0.03, -0.23], [-0.83, -0.31, -0.5], 6)
    tree = _tree([np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.31]]), tail, spur])
    tree.branch_r[:] = [0.2, 0.024, 0.046]
    leaves = np.array([1 + len(tail), len(tree.nodes) - 1])
    for attach in (False, True):
        C = match_cost(template, tree, BODY, ["tail"], leaves, attach=attach)[0]
        assert C[0] < C[1]


def test_a_short_tail_ending_in_one_hips_flank_is_missing_a_tail_swung_aside_stays(template):
    """A giraffe's skeleton may join its tail to the hind legs, leaving a free end only for a
    short spur out of one hip: the best end for the tail, ending in that hip's flank, a quarter
    of the body's thickest radius off the mid-plane. A tail leaves the body on the mid-plane
    and hangs there (standing animals' tails end within a tenth of that radius of it) or swings
    aside at its full length (a posed horse's): the spur is no tail, and the tail is missing (a
    stand-in where the template puts it) rather than named on a hip; a tail on the mid-plane, a
    long tail swung aside and the legs stay."""
    half = np.array([0.5, 0.2, 0.8])
    body = BodyFrame(np.eye(3), np.zeros(3), half)
    spur = np.linspace([-0.7, 0.05, -0.3], [-0.8, 0.25, -0.4], 4)        # 0.07 long
    real = np.linspace([-0.7, 0.0, -0.3], [-0.9, 0.02, -0.4], 4)
    swung = np.linspace([-0.7, 0.0, -0.3], [-1.0, 0.6, -0.6], 6)         # 0.3 long
    legs = [np.linspace([-0.7, 0.2, -0.3], [-0.7, 0.5, -0.9], 4),
            np.linspace([-0.7, -0.2, -0.3], [-0.7, -0.5, -0.9], 4)]
    core = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.01]])
    for tail, kept in ((spur, False), (real, True), (swung, True)):
        tree = _tree([b * half for b in (core, tail, *legs)])
        tree.radius[0] = 0.2                            # the body's thickest part
        ends = np.cumsum([len(core), len(tail), len(legs[0]), len(legs[1])]) - 1
        assign = {"tail": int(ends[1]), "leg_bl": int(ends[2]), "leg_br": int(ends[3])}
        got = match_module._on_mid_plane(template, tree, body, assign)
        want = dict(assign) if kept else {k: v for k, v in assign.items() if k != "tail"}
        assert got == want
