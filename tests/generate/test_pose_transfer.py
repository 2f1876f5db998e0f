"""Pose transfer between bodies (ngc_gen.generate.pose_transfer): body A moved as body B moves."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ngc_gen.data.errors import DataError
from ngc_gen.generate.pose_transfer import PoseTransfer, transfer_triples
from ngc_gen.models.shape_decoder import GCSlot, GCTemplate

KEYS = (0.0, 0.5, 1.0)
TEMPLATE = GCTemplate([GCSlot("torso", 3, (0.0, 1.0, 0.0), KEYS),
                       GCSlot("neck", 2, (1.0, 0.0, 0.0), KEYS),
                       GCSlot("head", 2, (1.0, 0.0, 0.0), KEYS),
                       GCSlot("leg", 3, (0.0, 0.0, 1.0), KEYS)])
PARENTS = {"torso": None, "neck": "torso", "head": "neck", "leg": "torso"}
SL = {(g, f): s for g, f, s in TEMPLATE.fields()}


def body(scale=1.0, neck=0.3, leg=0.5, seed=0, noise=0.003):
    """A stick animal: torso along z, a neck up and forward, a head on it, a leg down."""
    rng = np.random.default_rng(seed)
    th = np.zeros(TEMPLATE.size)
    torso = np.array([[0, 0, -0.4], [0, 0.02, -0.13], [0, 0.02, 0.13], [0, 0, 0.4]]) * scale
    neck_p = torso[-1] + np.linspace(0, 1, 3)[:, None] * np.array([0, neck, 0.1])
    head_p = neck_p[-1] + np.linspace(0, 1, 3)[:, None] * np.array([0, 0.02, 0.2 * scale])
    leg_p = torso[0] + np.linspace(0, 1, 4)[:, None] * np.array([0, -leg, 0.02])
    for g, p in (("torso", torso), ("neck", neck_p), ("head", head_p), ("leg", leg_p)):
        th[SL[(g, "points")]] = (p + rng.normal(0, noise, p.shape)).ravel()
        th[SL[(g, "log_radii")]] = np.log(0.05 * scale) + rng.normal(0, 0.1, 6)
        th[SL[(g, "twist")]] = rng.normal(0, 5, 3)
        th[SL[(g, "log_caps")]] = np.log(0.02)
    return th


def pts(th, g):
    return th[SL[(g, "points")]].reshape(-1, 3)


def swing_leg(th, degrees):
    """The leg turned about its start (the hip) around x."""
    out = th.copy()
    p = pts(th, "leg")
    R = Rotation.from_euler("x", degrees, degrees=True).as_matrix()
    out[SL[("leg", "points")]] = ((p - p[0]) @ R.T + p[0]).ravel()
    return out


@pytest.fixture
def pt():
    return PoseTransfer(TEMPLATE, PARENTS)


def test_a_body_moved_by_its_own_pose_change_lands_on_that_pose(pt):
    q, p = body(seed=1), swing_leg(body(seed=1), 35.0)
    p[SL[("neck", "points")]] += 0.02  # the neck slides and bends as well
    out = pt(q[None], q[None], p[None])[0]
    np.testing.assert_allclose(out, p, atol=1e-12)


def test_no_pose_change_leaves_the_other_body_as_it_is(pt):
    a, b = body(scale=1.3, neck=0.5, seed=2), body(seed=3)
    np.testing.assert_allclose(pt(a[None], b[None], b[None])[0], a, atol=1e-12)


def test_a_whole_body_move_carries_over_exactly(pt):
    """B turned, scaled and shifted as a whole: A turns, scales and shifts with it."""
    a, b = body(scale=1.3, neck=0.5, leg=0.7, seed=4), body(seed=5)
    R = Rotation.from_euler("xyz", [20, -35, 10], degrees=True).as_matrix()
    c, t = 0.8, np.array([0.1, -0.2, 0.05])

    def move(th):
        out = th.copy()
        for g in PARENTS:
            out[SL[(g, "points")]] = (c * pts(th, g) @ R.T + t).ravel()
        return out

    out = pt(a[None], b[None], move(b)[None])[0]
    for g in PARENTS:
        np.testing.assert_allclose(pts(out, g), pts(move(a), g), atol=1e-9, err_msg=g)


def test_a_leg_swing_turns_the_other_bodys_leg_about_its_own_hip(pt):
    a, b = body(scale=1.2, leg=0.8, seed=6), body(seed=7)
    out = pt(a[None], b[None], swing_leg(b, 40.0)[None])[0]
    la, lo = pts(a, "leg"), pts(out, "leg")
    np.testing.assert_allclose(lo[0], la[0], atol=1e-9)                # the hip stays
    np.testing.assert_allclose(np.linalg.norm(lo[-1] - lo[0]), np.linalg.norm(la[-1] - la[0]))
    cos = (lo[-1] - lo[0]) @ (la[-1] - la[0]) / np.linalg.norm(la[-1] - la[0]) ** 2
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))) == pytest.approx(40.0, abs=0.5)
    for g in ("torso", "neck", "head"):                                  # nothing else moves
        np.testing.assert_allclose(pts(out, g), pts(a, g), atol=1e-9, err_msg=g)
    np.testing.assert_allclose(out[SL[("leg", "log_radii")]], a[SL[("leg", "log_radii")]])


def test_a_child_follows_its_parent(pt):
    """B's neck lifts (in its own plane, so the turn is exact): A's head, the neck's child,
    stays on A's neck's end."""
    a, b = body(scale=1.1, neck=0.6, seed=8, noise=0.0), body(seed=9, noise=0.0)
    p = b.copy()
    n = pts(b, "neck")
    R = Rotation.from_euler("x", -30, degrees=True).as_matrix()
    p[SL[("neck", "points")]] = ((n - n[0]) @ R.T + n[0]).ravel()
    h = pts(b, "head")
    p[SL[("head", "points")]] = ((h - n[0]) @ R.T + n[0]).ravel()
    out = pt(a[None], b[None], p[None])[0]
    gap_before = pts(a, "head")[0] - pts(a, "neck")[-1]
    gap_after = pts(out, "head")[0] - pts(out, "neck")[-1]
    np.testing.assert_allclose(gap_after, gap_before @ R.T, atol=1e-9)


def test_radius_twist_and_cap_changes_carry_over_as_changes(pt):
    a, b = body(scale=1.4, seed=10), body(seed=11)
    p = b.copy()
    p[SL[("torso", "log_radii")]] += 0.1
    p[SL[("leg", "twist")]] += 12.0
    out = pt(a[None], b[None], p[None])[0]
    np.testing.assert_allclose(out[SL[("torso", "log_radii")]], a[SL[("torso", "log_radii")]] + 0.1)
    np.testing.assert_allclose(out[SL[("leg", "twist")]], a[SL[("leg", "twist")]] + 12.0)


def test_triples_pair_every_body_with_the_others_poses_through_a_shared_one():
    bodies = ["horse", "horse_white", "fox"]
    names = ["horse_walk_00", "horse_walk_01", "horse_white_walk_00", "horse_white_idle_00",
             "fox_idle_00", "fox_run_00", "cat_walk_00"]
    theta = np.stack([body(seed=i) for i in range(len(names))])
    pidx = np.arange(SL[("torso", "points")].start, SL[("leg", "points")].stop)
    tri = transfer_triples(theta, names, bodies, pidx, poses="all")
    got = {(names[a], names[b], names[p]) for a, b, p in tri}
    assert ("horse_walk_00", "horse_white_walk_00", "horse_white_idle_00") in got
    assert ("horse_white_idle_00", "fox_idle_00", "fox_run_00") in got  # horse_white, not horse
    assert not any(n.startswith("cat") for t in got for n in t)         # no body: not used
    assert not any(a.split("_")[0] == "fox" and b.startswith("horse_w") is False and
                   b.startswith("horse") for a, b, _ in got)            # fox and horse share none
    # every triple: A and B at the same pose q, A and B different bodies
    for a, b, _ in got:
        assert a.rsplit("_", 2)[-2:] == b.rsplit("_", 2)[-2:] and a != b
    assert len(got) == len(tri) == 2 + 2 + 2 + 2  # horse<->horse_white, horse_white<->fox


def test_by_default_a_body_is_moved_only_to_the_poses_it_lacks():
    names = ["horse_walk_00", "horse_walk_01", "horse_white_walk_00", "horse_white_idle_00",
             "fox_idle_00", "fox_run_00"]
    theta = np.stack([body(seed=i) for i in range(len(names))])
    pidx = np.arange(SL[("torso", "points")].start, SL[("leg", "points")].stop)
    got = {(names[a], names[p]) for a, _, p in
           transfer_triples(theta, names, ["horse", "horse_white", "fox"], pidx)}
    assert got == {("horse_walk_00", "horse_white_idle_00"),      # the horse has no idle
                   ("horse_white_walk_00", "horse_walk_01"),
                   ("horse_white_idle_00", "fox_run_00"),
                   ("fox_idle_00", "horse_white_walk_00")}


def test_the_shared_pose_nearest_the_target_is_the_one_used():
    names = ["a_x_00", "a_y_00", "b_x_00", "b_y_00", "b_z_00"]
    theta = np.stack([body(seed=0)] * 5)
    theta[4] = swing_leg(theta[4], 30)
    theta[3] = swing_leg(theta[3], 25)   # b's y is nearer b's z than b's x is
    pidx = np.arange(SL[("leg", "points")].start, SL[("leg", "points")].stop)
    tri = transfer_triples(theta, names, ["a", "b"], pidx)
    assert [1, 3, 4] in tri.tolist()


def test_bad_setups_say_what_to_fix():
    with pytest.raises(DataError, match="no parent for \\['leg'\\]"):
        PoseTransfer(TEMPLATE, {"torso": None, "neck": "torso", "head": "neck"})
    with pytest.raises(DataError, match="one root"):
        PoseTransfer(TEMPLATE, {**PARENTS, "leg": None})
    with pytest.raises(DataError, match="poses must be one of"):
        transfer_triples(np.stack([body()] * 2), ["wolf_a_00", "fox_a_00"], ["wolf", "fox"],
                         np.arange(3), poses="some")
    with pytest.raises(DataError, match="two bodies or more"):
        transfer_triples(np.stack([body()] * 2), ["wolf_a_00", "wolf_b_00"], ["wolf", "fox"],
                         np.arange(3))
