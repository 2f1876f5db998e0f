"""Template transfer: the quadruped template's GCs on meshes without a rig (same names, order,
degrees and keys), parts where they belong, a posed head found within its reach (the second
pass), a stubby tail found on the finer tree, a missing part reported, unmatchable meshes
refused, an edit program written with template names run on every mesh, templates exported."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml
from scipy.optimize import linear_sum_assignment

from ngc_gen.data.autogc.frame import moved_gcs
from ngc_gen.data.autogc.orient import Orientation
from ngc_gen.data.autogc.template import load_template, template_from_dict
from ngc_gen.data.autogc.transfer import (START_REACH, BodyFrame, TransferSettings, Tree,
                                          _front_to_back, _inferred_tree,
                                          _reach_back, export_template, match_cost,
                                          transfer_template)
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import normalize
from ngc_gen.data.mesh.sampling import sample_surface
from ngc_gen.edit.program import EditProgram, apply_program

from ...helpers import ROOT
from .shapes import chair, quadruped, sphere, torus

pytestmark = pytest.mark.usefixtures("single_thread")
TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
FAST = TransferSettings.from_yaml(resolution=64, samples=5000)
Z_UP = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # y-up/+z front -> z-up/+x front


def _normalised(mesh, points):
    m, center, scale = normalize(mesh)
    return m, {k: (v - center) * scale for k, v in points.items()}


@pytest.fixture(scope="module")
def template():
    return load_template(TEMPLATE)


@pytest.fixture(scope="module")
def transfers(template):
    """name -> (mesh, named points, Transfer): a y-up quadruped facing +z and a longer one with
    shorter legs turned to z-up facing +x (both orientations detected)."""
    out = {}
    for name, (mesh, pts) in {"yup": quadruped(),
                              "zup": quadruped(1.0, 0.6, 0.35, 0.5, rotation=Z_UP)}.items():
        m, p = _normalised(mesh, pts)
        out[name] = (m, p, transfer_template(m, template, FAST, name))
    return out


def test_every_mesh_gets_the_templates_gcs_and_its_parts_land_in_them(template, transfers):
    for name, (mesh, pts, tr) in transfers.items():
        assert [g.name for g in tr.gcs] == template.names, name
        for g, t in zip(tr.gcs, template.gcs):
            d = g.to_dict()
            assert len(d["curve"]["points"]) == t.degree + 1, (name, g.name)
            assert [k["t"] for k in d["keys"]] == list(t.keys), (name, g.name)
        assert tr.missing == [] and tr.coverage >= 0.999, name
        by = {g.name: g for g in tr.gcs}
        for point, gc, other in (("foot_fl", "leg_fl", "leg_fr"), ("head_tip", "head", "tail"),
                                 ("tail_tip", "tail", "head"), ("torso", "torso", "leg_bl")):
            q = pts[point][None]
            assert bool(by[gc].contains(q)[0]), (name, point, gc)
            assert not bool(by[other].contains(q)[0]), (name, point, other)
    assert transfers["yup"][2].orientation.describe() == "up +y (detected), front +z (detected)"
    assert transfers["zup"][2].orientation.describe() == "up +z (detected), front +x (detected)"


def test_a_grazing_head_far_from_the_templates_place_is_found_within_its_reach(template):
    """The head lowered to the ground lies far from where the template's head sits, too far for
    the first matching pass; the second gives it the free end left over at the neck and head's
    length from where the neck attaches, so the head is matched and holds the snout, and no
    leg took it (axes given, as for a collection: this is about matching, not orientation)."""
    mesh, pts = _normalised(*quadruped(grazing=True))
    tr = transfer_template(mesh, template, dataclasses.replace(FAST, up="+y", front="+z"),
                           "grazing")
    assert tr.missing == [] and "head" in tr.matched
    by = {g.name: g for g in tr.gcs}
    snout = pts["head_tip"][None]
    assert bool(by["head"].contains(snout)[0])
    assert not any(bool(by[leg].contains(snout)[0]) for leg in ("leg_fl", "leg_fr"))
    assert bool(by["leg_fl"].contains(pts["foot_fl"][None])[0])


def test_a_stubby_tail_pruned_with_the_spurs_is_found_on_the_finer_tree(template):
    """A short thick tail straight back sticks out of the torso's end by less than a spur must
    (min_branch_length x its thickness): the skeleton tree loses it and the tail is missing
    after both passes. Matched once more on the finer tree (spurs FINER x as long kept), the
    tail is found: nothing missing, and the tail GC holds the tail's tip, not a small stand-in
    at its attachment."""
    mesh, pts = _normalised(*quadruped(tail=0.19, tail_radius=0.05, tail_dir=(0.0, 1.0)))
    tr = transfer_template(mesh, template, FAST, "stubby tail")
    assert tr.missing == [] and "tail" in tr.matched
    by = {g.name: g for g in tr.gcs}
    assert bool(by["tail"].contains(pts["tail_tip"][None])[0])
    assert not bool(by["torso"].contains(pts["tail_tip"][None])[0])


def test_a_stub_tail_the_skeleton_never_finds_still_gets_a_tail_gc_over_it(template):
    """A tail this short (a deer's) is pruned even on the finer tree, so it is missing; its GC
    still reaches from the torso to the stub and holds the stub's tip, as a rig's tail GC
    would (not a small stand-in inside the torso)."""
    mesh, pts = _normalised(*quadruped(tail=0.1, tail_radius=0.05, tail_dir=(0.0, 1.0)))
    tr = transfer_template(mesh, template, FAST, "stub tail")
    assert tr.missing == ["tail"]
    tail = tr.gcs[template.names.index("tail")]
    assert bool(tail.contains(pts["tail_tip"][None])[0])
    assert not bool(tail.contains(pts["torso"][None])[0])


def test_a_tail_that_tapers_out_of_the_body_is_held_from_its_root_to_its_tip(template):
    """A crocodile's tail tapers out of the body, as thick as the body at its root, so the
    skeleton's tail branch leaves the surface well behind the hips, where the tail has thinned;
    the tail GC must still hold the tail's root (the rearmost root part reaches back to the
    found hind legs' row). The body is a crocodile's: long and low on short legs, a thick neck
    holding a big head up. (A thin raised neck with a small head on such a tail leaves the two
    ends alike in surface, thickness and height: docs/transfer.md, "Orientation".)"""
    mesh, pts = _normalised(*quadruped(length=1.0, leg=0.3, neck=0.3, neck_radius=0.12,
                                       head=(0.4, 0.12), tail=0.9, tail_dir=(0.0, 1.0),
                                       tail_radius=(0.16, 0.13, 0.1, 0.07, 0.04)))
    tr = transfer_template(mesh, template, FAST, "tapering tail")
    by = {g.name: g for g in tr.gcs}
    assert tr.missing == [] and bool(by["head"].contains(pts["head_tip"][None])[0])
    assert bool(by["tail"].contains(pts["tail_tip"][None])[0])
    assert bool(by["tail"].contains(pts["tail_root"][None])[0])


def test_a_galloping_front_foot_behind_the_hind_foot_keeps_its_legs_name(template):
    """Left side of a gallop: the front foot lands behind the hind foot, so by where the feet
    are the two legs swap; where each skeleton branch leaves the body (shoulder in front, hip
    behind) names them right. Without the attachment term they swap (the test can fail)."""
    legs = ["leg_fl", "leg_bl"]
    tips = np.array([[-0.3, 0.5, -0.9], [-0.1, 0.5, -0.9]])     # front foot, hind foot
    roots = np.array([[0.25, 0.3, 0.0], [-0.55, 0.3, 0.1]])     # shoulder, hip
    nodes = np.vstack([tips, [[0.0, 0.0, 0.2]]])
    tree = Tree(nodes=nodes, radius=np.full(3, 0.1), graph=None, main=np.ones(3, bool),
                branch_of=np.array([0, 1, 2]),
                branch_dir=np.array([[0, 0, -1.0], [0, 0, -1.0], [0, 0, 0]]),
                branch_r=np.array([0.05, 0.05, 0.1]), branch_root=np.vstack([roots, nodes[2:]]))
    body = BodyFrame(np.eye(3), np.zeros(3), np.ones(3))
    for attach, want in ((True, [0, 1]), (False, [1, 0])):
        C = match_cost(template, tree, body, legs, np.array([0, 1]), attach=attach)
        assert list(linear_sum_assignment(C)[1]) == want, attach


def test_a_crossed_pair_on_one_side_is_named_by_where_its_legs_leave_the_body(template):
    """When the matching still gives a gallop's front leg the hind foot (each foot at the other's
    place), the pair on that side is swapped back: the front leg's branch leaves the body at
    the shoulder. Legs that leave at one place (a dog's skeleton joining them mid-body) and a
    left leg against a right one are left as matched."""
    roots = np.array([[0.25, 0.3, 0.0], [-0.55, 0.3, 0.1], [0.25, -0.3, 0.0], [0.1, 0.3, 0.1]])
    nodes = np.array([[-0.3, 0.5, -0.9], [-0.1, 0.5, -0.9], [0.3, -0.5, -0.9], [0.0, 0.5, -0.9]])
    tree = Tree(nodes=nodes, radius=np.full(4, 0.1), graph=None, main=np.ones(4, bool),
                branch_of=np.arange(4), branch_dir=np.tile([0, 0, -1.0], (4, 1)),
                branch_r=np.full(4, 0.05), branch_root=roots)
    body = BodyFrame(np.eye(3), np.zeros(3), np.ones(3))
    crossed = {"leg_fl": 1, "leg_bl": 0, "leg_fr": 2}       # front-left took the hip's branch
    assert _front_to_back(template, tree, body, crossed) == {"leg_fl": 0, "leg_bl": 1, "leg_fr": 2}
    assert _front_to_back(template, tree, body, {"leg_fl": 0, "leg_bl": 1}) == \
        {"leg_fl": 0, "leg_bl": 1}                              # already right
    near = {"leg_fl": 3, "leg_bl": 0}   # 0.15 apart (under SIGMA_ATTACH): the matching stands
    assert _front_to_back(template, tree, body, near) == near
    assert _front_to_back(template, tree, body, {"leg_fr": 1, "leg_bl": 2}) == \
        {"leg_fr": 1, "leg_bl": 2}                              # two sides: not a pair


def test_a_part_on_the_root_reaches_back_toward_its_template_start():
    """A leg's skeleton path begins below the hip (where it leaves the body); a rig's leg starts
    at the hip joint. The path is extended back along itself toward the template's start, by
    at most START_REACH x its top radius, and not at all when the start lies ahead of it."""
    leg = np.stack([np.zeros(20), np.zeros(20), np.linspace(0.0, -1.0, 20)], 1)  # down from 0
    ident = lambda p: np.asarray(p)  # noqa: E731  (body frame = world)
    near = _reach_back(leg, ident, np.array([0.0, 0.0, 0.1]), radius=0.2)
    assert np.allclose(near[0], [0.0, 0.0, 0.1]) and np.allclose(near[-1], leg[-1])
    far = _reach_back(leg, ident, np.array([0.0, 0.3, 1.0]), radius=0.2)
    assert np.allclose(far[0], [0.0, 0.0, START_REACH * 0.2])  # along itself, capped
    assert _reach_back(leg, ident, np.array([0.0, 0.0, -0.5]), radius=0.2) is leg


def test_a_mesh_without_a_tail_gets_a_small_tail_at_its_attachment(template):
    mesh, pts = _normalised(*quadruped(tail=0))
    tr = transfer_template(mesh, template, FAST, "tailless")
    assert tr.missing == ["tail"] and [g.name for g in tr.gcs] == template.names
    tail = tr.gcs[template.names.index("tail")]
    torso = tr.gcs[template.names.index("torso")]
    lo, hi = (np.asarray(b) for b in tail.bounds())
    tlo, thi = (np.asarray(b) for b in torso.bounds())
    assert (hi - lo).max() < 0.5 * (thi - tlo).max()  # small
    start = np.asarray(tail.to_world(np.array([[-1.0, 0.0, 0.0]])))
    assert bool(torso.contains(start)[0])  # at its attachment on the torso


@pytest.mark.parametrize("make", [chair, torus, sphere])
def test_a_mesh_of_another_kind_is_refused_in_one_line(template, make):
    mesh, _, _ = normalize(make())
    with pytest.raises(DataError, match="does not match template quadruped|free ends") as e:
        transfer_template(mesh, template, FAST, make.__name__)
    assert "\n" not in str(e.value) and str(TEMPLATE) in str(e.value)


def test_an_edit_program_with_template_names_runs_on_every_mesh(transfers):
    program = EditProgram.from_dict({"name": "raise_leg", "ops": [
        {"op": "handles", "gc": "leg_fl", "at": [0.85, 1.0], "fixed": ["torso"],
         "rotate": {"axis": [1.0, 0.0, 0.0], "degrees": 40, "pivot": {"gc": "leg_fl", "t": 0.0}}}]})
    for name, (_, _, tr) in transfers.items():
        after = {g.name: g for g in apply_program(program, tr.gcs).gcs}
        before = {g.name: g for g in tr.gcs}
        end = np.array([[1.0, 0.0, 0.0]])
        moved = np.linalg.norm(np.asarray(after["leg_fl"].to_world(end)) -
                               np.asarray(before["leg_fl"].to_world(end)))
        assert moved > 0.05, name
        assert after["torso"].to_dict() == before["torso"].to_dict(), name


def test_exported_template_loads_and_transfers(template, transfers, tmp_path):
    shapes = []
    for mesh, _, tr in transfers.values():
        pts, _ = sample_surface(mesh.vertices, mesh.faces, 5000, np.random.default_rng(0))
        shapes.append((tr.gcs, pts, tr.orientation))
    out = export_template(shapes, "mine", template)
    path = tmp_path / "mine.yaml"
    path.write_text(out.to_yaml())
    back = load_template(path)
    assert back.names == template.names and back.placed
    assert [g.parent for g in back.gcs] == [g.parent for g in template.gcs]
    # from one annotated mesh alone (no template): the tree is inferred
    alone = export_template(shapes[:1], "inferred")
    tree = template_from_dict(yaml.safe_load(alone.to_yaml()))
    parents = {g.name: g.parent for g in tree.gcs}
    assert parents["torso"] is None and parents["leg_fl"] == "torso" and parents["head"] == "neck"
    assert {g.name: g.symmetric for g in tree.gcs}["leg_fl"] == "leg_fr"


def _tube(name, a, b, r):
    from ngc_gen.geometry import GeneralizedCylinder

    a, b = np.asarray(a, float), np.asarray(b, float)
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": [a.tolist(), ((a + b) / 2).tolist(),
                                                             b.tolist()]},
        "up": [1.0, 0.0, 0.0] if abs(b - a)[2] > abs(b - a)[0] else [0.0, 0.0, 1.0],
        "keys": [{"t": 0.0, "radii": [r, r]}, {"t": 1.0, "radii": [r, r]}], "caps": [r, r]})


def test_an_inferred_tree_hangs_a_shoulder_inside_the_neck_base_on_the_torso():
    """A rig's front leg starts at a shoulder joint high in the chest, where the neck's base is
    too: deeper in the neck than in the torso, but inside both, it belongs to the torso; a head
    larger than its neck still hangs on the neck (no "parents are larger" rule)."""
    gcs = [_tube("torso", (-1.0, 0, 0), (1.0, 0, 0), 0.4),
           _tube("neck", (0.8, 0, 0.2), (1.2, 0, 0.8), 0.15),
           _tube("head", (1.2, 0, 0.8), (1.9, 0, 0.8), 0.3),
           _tube("leg", (0.85, 0.0, 0.28), (0.85, 0.0, -1.2), 0.12)]
    from ngc_gen.data.autogc.transfer import _attachment

    A = _attachment(gcs).min(2)
    assert A[3, 1] < A[3, 0] <= 1.0            # the leg's top: deeper in the neck, in both
    pts = np.concatenate([np.asarray(g.to_world(np.random.default_rng(0).uniform(-1, 1, (200, 3))))
                          for g in gcs])
    body = BodyFrame.of(pts, Orientation(np.array([0.0, 0, 1]), np.array([1.0, 0, 0])))
    parents = {t.name: t.parent for t in _inferred_tree(gcs, body)}
    assert parents == {"torso": None, "neck": "torso", "head": "neck", "leg": "torso"}


def test_a_template_without_places_says_how_to_get_one(template):
    bare = dataclasses.replace(template, gcs=tuple(dataclasses.replace(g, place=None)
                                                   for g in template.gcs))
    with pytest.raises(DataError, match="export_template"):
        transfer_template(quadruped()[0], bare, FAST)


def test_settings_come_from_the_annotate_group_and_refuse_an_unknown_key():
    """The whole `annotate` group (the runner's and the automatic GCs' keys are theirs) builds
    the settings with conf/annotate/default.yaml's values; a key the group does not have is
    refused with its name and the file, not dropped."""
    conf = yaml.safe_load((ROOT / "conf/annotate/default.yaml").read_text())
    st = TransferSettings.from_config({**conf, "min_matched": 0.5})
    assert st == TransferSettings.from_yaml(min_matched=0.5)
    assert st.missing_cost == conf["missing_cost"] and st.refine_steps == conf["refine_steps"]
    with pytest.raises(DataError, match=r"conf/annotate/default.yaml.*annotate.refine_step\b"):
        TransferSettings.from_config({**conf, "refine_step": 10})


def test_a_mesh_lying_on_its_side_keeps_the_folders_layout(template, transfers):
    """The collection's up given (+y) but one animal lies on its side (a death clip): it is
    matched with its own up (the given axes overruled, with a warning), and written in the
    template's frame its GCs have the up vectors every other mesh of the folder has (a
    shape-latent model needs one layout)."""
    side = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # +y up -> +x
    given = dataclasses.replace(FAST, up="+y", front="+z")
    m, p = _normalised(*quadruped(rotation=side))
    tr = transfer_template(m, template, given, "lying")
    upright = transfer_template(transfers["yup"][0], template, given, "upright")
    assert tr.source == "detected" and tr.warnings and upright.source == "given"
    assert np.allclose([g.to_dict()["up"] for g in moved_gcs(tr.gcs, tr.rotation, np.zeros(3), 1.0)],
                       [g.to_dict()["up"] for g in moved_gcs(upright.gcs, upright.rotation,
                                                             np.zeros(3), 1.0)], atol=1e-6)
    by = {g.name: g for g in tr.gcs}
    for point, gc in (("foot_fl", "leg_fl"), ("head_tip", "head"), ("tail_tip", "tail")):
        assert bool(by[gc].contains(p[point][None])[0]), (point, gc)


def test_a_gathered_gallops_legs_are_named_by_where_they_leave_the_body(template):
    """A gathered gallop (a fox's): the hind feet land under the belly, in front of where the
    front feet reach, and the front-left foot pressed against the left hind leg has no free end
    of its own. Named by where the feet are, the right hind foot took leg_fr, the right front
    foot leg_br and the left hind foot leg_fl. Where each leg's path leaves the body (the
    hips with the tail, the shoulder) names them: the right pair swaps, the left leg alone is
    the hind one, as the right hind leg that leaves the body where it does. A standing animal,
    and a skeleton joining a pair mid-body (starts within START_SLACK), keep their names."""
    from ngc_gen.data.autogc.transfer.leg_order import START_SLACK, _legs_by_start

    starts = {"leg_fl": -0.12, "leg_fr": -0.12, "leg_br": 0.18, "head": 0.75, "tail": -0.11}
    nodes = np.array([[x, 0.0, 0.0] for x in starts.values()])
    paths = {n: np.array([i]) for i, n in enumerate(starts)}
    by_feet = {n: 10 + i for i, n in enumerate(starts)}
    named = _legs_by_start(template, nodes, by_feet, paths)
    assert named == {"leg_fr": by_feet["leg_br"], "leg_br": by_feet["leg_fr"],
                     "leg_bl": by_feet["leg_fl"], "head": by_feet["head"],
                     "tail": by_feet["tail"]}
    standing = {"leg_fl": 0.25, "leg_fr": 0.25, "leg_bl": -0.57, "leg_br": -0.57}
    nodes = np.array([[x, 0.0, 0.0] for x in standing.values()])
    paths = {n: np.array([i]) for i, n in enumerate(standing)}
    assign = {n: 10 + i for i, n in enumerate(standing)}
    assert _legs_by_start(template, nodes, assign, paths) == assign
    joined = {"leg_fl": 0.0, "leg_bl": START_SLACK / 2}      # one junction mid-body
    nodes = np.array([[x, 0.0, 0.0] for x in joined.values()])
    paths = {n: np.array([i]) for i, n in enumerate(joined)}
    assign = {n: 10 + i for i, n in enumerate(joined)}
    assert _legs_by_start(template, nodes, assign, paths) == assign
