"""The junction measure on a scene with a known answer: two overlapping capsules (an arm along
-x, a thinner one along +y, meeting at the origin), each inside a GC 10% wider than itself."""
import inspect

import numpy as np
import pytest
import trimesh
from skimage.measure import marching_cubes

from ngc_gen.eval.junctions import (boundary_faces, extra_pieces, junction_mask, junction_metrics,
                                    solid_pieces, worst_junction)
from ngc_gen.geometry import GeneralizedCylinder

A = (np.array([-0.6, 0.0, 0.0]), np.array([0.0, 0.0, 0.0]), 0.2)
B = (np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.0]), 0.15)
AWAY = np.array([-0.45, 0.0, 0.2])        # on A's side, far from B


def capsule_sdf(p, a, b, r):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1) - r


def level_set(res=64):
    """The union of the two capsules (exact min of their distances), marching cubes."""
    x = np.linspace(-1.0, 1.0, res)
    g = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)
    f = np.minimum(capsule_sdf(g, *A), capsule_sdf(g, *B)).reshape(res, res, res)
    v, faces, _, _ = marching_cubes(f, 0.0, spacing=(x[1] - x[0],) * 3)
    return trimesh.Trimesh(v - 1.0, faces[:, ::-1], process=False)


def gc(name, a, b, r):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": [a.tolist(), b.tolist()]},
        "keys": [{"t": 0.0, "radii": [r, r]}], "caps": [r, r]})


@pytest.fixture(scope="module")
def scene():
    truth = level_set()
    gcs = [gc("a", A[0], A[1], 1.1 * A[2]), gc("b", B[0], B[1], 1.1 * B[2])]
    return truth, gcs


def displaced(truth, centre, height=0.03, sigma=0.1):
    """The truth with every vertex moved out along its normal by a small wave everywhere
    (0.002 +- 0.001: a little error in distance and normal all over) plus a Gaussian bump of
    `height` at `centre`."""
    v = np.asarray(truth.vertices)
    d = 0.002 + 0.001 * np.sin(25.0 * v[:, 0]) * np.cos(25.0 * v[:, 1])
    d = d + height * np.exp(-((v - centre) ** 2).sum(1) / (2 * sigma ** 2))
    return trimesh.Trimesh(v + d[:, None] * truth.vertex_normals, truth.faces, process=False)


def test_junction_samples_are_where_both_gcs_reach(scene):
    _, gcs = scene
    pts = np.array([[0.0, 0.0, 0.0],        # inside both
                    [-0.5, 0.0, 0.0],       # inside a only, far from b
                    [0.0, 0.5, 0.0],        # inside b only, far from a
                    [-0.1, 0.23, 0.0],      # inside b, just past a's boundary (rho_a 1.05)
                    [-0.1, 0.35, 0.0]])     # inside b, well past a's boundary (rho_a 1.6)
    assert junction_mask(pts, gcs, 0.1).tolist() == [True, False, False, True, False]
    assert junction_mask(pts, gcs, 0.0).tolist() == [True, False, False, False, False]
    assert not junction_mask(pts, gcs[:1], 0.1).any()     # one GC: no junction


def bumped(scene) -> tuple[dict, dict]:
    """The scene's metrics with a bump at its highest junction vertex, and with one elsewhere."""
    truth, gcs = scene
    j = junction_mask(truth.vertices, gcs, 0.1)
    at_junction = truth.vertices[j][np.argmax(truth.vertices[j][:, 1])]
    return (junction_metrics(displaced(truth, at_junction), truth, gcs),
            junction_metrics(displaced(truth, AWAY), truth, gcs))


def test_a_bump_at_the_junction_raises_the_ratio_and_one_elsewhere_lowers_it(scene):
    seam, away = bumped(scene)
    assert 0.02 < seam["junction_share"] < 0.2
    assert seam["junction_ratio_dist"] > 2.0 and seam["junction_ratio_normal"] > 2.0
    assert away["junction_ratio_dist"] < 0.8 and away["junction_ratio_normal"] < 0.8
    assert seam["extra_pieces"] == away["extra_pieces"] == 0


def test_the_worst_junction_is_found_at_the_bump(scene):
    """The close-up of a seam looks where it is: the junction sample whose neighbourhood is
    furthest from the truth sits on a bump at the junction; a bump elsewhere is not picked."""
    truth, gcs = scene
    j = junction_mask(truth.vertices, gcs, 0.1)
    at_junction = truth.vertices[j][np.argmax(truth.vertices[j][:, 1])]
    centre, err = worst_junction(displaced(truth, at_junction, sigma=0.04), truth, gcs, 0.05)
    assert np.linalg.norm(centre - at_junction) < 0.06 and err > 0.01
    centre, err = worst_junction(displaced(truth, AWAY, sigma=0.04), truth, gcs, 0.05)
    assert np.linalg.norm(centre - AWAY) > 0.2 and err < 0.005
    assert worst_junction(truth, truth, gcs[:1], 0.05) is None


def test_the_truth_itself_scores_one_and_no_extra_piece(scene):
    truth, gcs = scene
    m = junction_metrics(truth, truth, gcs)
    assert m["junction_ratio_dist"] == m["junction_ratio_normal"] == 1.0
    assert m["junction_dist"] == m["elsewhere_dist"] == 0.0
    assert (m["extra_pieces"], m["pieces"], m["gt_pieces"]) == (0, 1, 1)
    one = junction_metrics(truth, truth, gcs[:1])       # one GC: no junction, no ratio
    assert one["junction_ratio_dist"] is None and one["junction_share"] == 0.0
    assert one["elsewhere_dist"] == 0.0


def test_the_grid_alone_makes_junctions_worse(scene):
    """The ceiling is not 1: marching cubes rounds the crease where the capsules meet (the exact
    union at 48^3 against 64^3: measured 2.0 in distance and in normal)."""
    truth, gcs = scene
    m = junction_metrics(level_set(48), truth, gcs)
    assert m["junction_ratio_dist"] > 1.5 and m["junction_ratio_normal"] > 1.5
    assert m["extra_pieces"] == 0


def test_a_loose_sphere_is_one_extra_piece(scene):
    truth, gcs = scene
    loose = trimesh.creation.icosphere(subdivisions=2, radius=0.05).apply_translation(
        [0.6, 0.5, 0.0])
    m = junction_metrics(trimesh.util.concatenate([truth, loose]), truth, gcs)
    assert (m["extra_pieces"], m["pieces"], m["gt_pieces"]) == (1, 2, 1)
    # the same sphere in the truth too: matched, not extra
    both = trimesh.util.concatenate([truth, loose])
    assert junction_metrics(both, both, gcs)["extra_pieces"] == 0


def test_a_cut_through_a_thick_part_is_extra_and_a_cut_sliver_is_not(scene):
    """The fit cut through capsule A (a gap of 0.04 at x = -0.4: the tip is loose) has one extra
    piece; a truth of two balls joined by a rod 0.004 thick, fitted without the rod, has none:
    the truth there is a sliver no grid resolves."""
    truth, gcs = scene
    res = 64
    x = np.linspace(-1.0, 1.0, res)
    g = np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)

    def mesh(f):
        v, faces, _, _ = marching_cubes(f.reshape(res, res, res), 0.0, spacing=(x[1] - x[0],) * 3)
        return trimesh.Trimesh(v - 1.0, faces[:, ::-1], process=False)

    union = np.minimum(capsule_sdf(g, *A), capsule_sdf(g, *B))
    cut = mesh(np.maximum(union, 0.02 - np.abs(g[:, 0] + 0.4)))
    m = junction_metrics(cut, truth, gcs)
    assert (m["extra_pieces"], m["pieces"], m["sliver_breaks"]) == (1, 2, 0)
    balls = [trimesh.creation.icosphere(3, radius=0.25).apply_translation([s, 0, 0])
             for s in (-0.4, 0.4)]
    rod = trimesh.creation.cylinder(radius=0.002, height=0.6, sections=12)
    rod.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    dumbbell = trimesh.util.concatenate([*balls, rod])
    fit = trimesh.util.concatenate(balls)
    pieces = junction_metrics(fit, dumbbell, gcs)
    assert (pieces["gt_pieces"], pieces["pieces"], pieces["extra_pieces"],
            pieces["sliver_breaks"]) == (1, 2, 0, 1)
    apart = junction_metrics(fit, trimesh.util.concatenate(balls), gcs)   # truly two: matched
    assert (apart["gt_pieces"], apart["extra_pieces"], apart["sliver_breaks"]) == (2, 0, 0)


def test_intersecting_true_pieces_are_one_solid(scene):
    """A truth made of two closed capsules through each other (like the ant's pieces) is one
    piece; its faces inside the other capsule are not part of the true surface."""
    fit, gcs = scene
    a = trimesh.creation.capsule(height=0.6, radius=A[2], count=[24, 24])
    a.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    a.apply_translation([-0.3, 0.0, 0.0])
    b = trimesh.creation.capsule(height=0.6, radius=B[2], count=[24, 24])
    b.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    b.apply_translation([0.0, 0.3, 0.0])
    truth = trimesh.util.concatenate([a, b])
    piece, n = solid_pieces(truth, join=0.01)
    assert n == 1 and len(np.unique(piece)) == 1
    outer = boundary_faces(truth)
    assert 0 < len(truth.faces) - len(outer.faces) < 0.3 * len(truth.faces)
    assert np.linalg.norm(outer.triangles_center, axis=1).min() > 0.1   # the inner caps are gone
    m = junction_metrics(fit, truth, gcs)
    assert (m["extra_pieces"], m["gt_pieces"]) == (0, 1)
    far = b.copy().apply_translation([0.0, 0.0, 0.5])   # apart: two pieces
    assert solid_pieces(trimesh.util.concatenate([a, far]), join=0.01)[1] == 2


def test_defaults_are_the_metrics_group():
    """The library's defaults are conf/metrics/default.yaml's `junctions` (one home)."""
    from ngc_gen.app.runtime.config import compose_config

    conf = compose_config(overrides=["stage=fit"]).metrics.junctions
    sig = inspect.signature(junction_metrics).parameters
    assert {k: sig[k].default for k in conf} == dict(conf)


def test_the_local_ratio_weighs_a_junction_against_the_parts_that_meet_there():
    """A part that is hard everywhere (GC 1, error 5) is no seam: junction samples between GCs
    0 and 2 with the error of those two parts score 1 against them, while the plain ratio, which
    compares them with the whole shape, calls them better than elsewhere; a junction twice as bad
    as its parts scores 2; a GC with under MIN_OWNED elsewhere samples falls back to the whole
    elsewhere mean."""
    from ngc_gen.eval.junctions import MIN_OWNED, local_ratio

    n = 100
    rho = np.full((3, 4 * n), np.inf)
    for g in range(3):                       # elsewhere samples deep in GC g alone
        rho[g, g * n:(g + 1) * n] = 0.5
    rho[0, 3 * n:], rho[2, 3 * n:] = 0.9, 0.95   # junction samples of GCs 0 and 2
    junction = np.arange(4 * n) >= 3 * n
    err = np.r_[np.full(n, 1.0), np.full(n, 5.0), np.full(n, 1.0), np.full(n, 1.0)]
    assert local_ratio(err, rho, junction) == pytest.approx(1.0)
    assert err[junction].mean() / err[~junction].mean() < 0.5      # the plain ratio
    assert local_ratio(np.where(junction, 2.0, err), rho, junction) == pytest.approx(2.0)
    few = np.arange(4 * n) < 2 * n + MIN_OWNED - 1      # GC 2 keeps too few samples to own
    keep = few | junction
    whole = err[keep & ~junction].mean()
    assert local_ratio(err[keep], rho[:, keep], junction[keep]) == pytest.approx(
        1.0 / (0.5 * (1.0 + whole)))
    assert local_ratio(err, rho, np.zeros(4 * n, bool)) is None


def test_the_local_ratio_sees_a_bump_at_the_junction_and_not_one_elsewhere(scene):
    seam, away = bumped(scene)
    for k in ("dist", "normal"):
        assert seam[f"junction_ratio_{k}_local"] > 2.0
        assert away[f"junction_ratio_{k}_local"] < 0.8


def test_true_parts_under_join_apart_are_one_piece_and_a_fit_may_keep_them_apart():
    """Two closed spheres 0.0098 apart (a point contact, under join = 0.01) are one true
    piece whatever the samples (an edit elsewhere must not change the count); a fit that keeps
    them apart, its small sphere a little off, has no extra piece: it lies on a true part no
    other fitted piece reaches (the ant's abdomen beside its waist)."""
    big = trimesh.creation.icosphere(3, radius=0.3)
    small = trimesh.creation.icosphere(2, radius=0.05).apply_translation([0.3598, 0, 0])
    truth = trimesh.util.concatenate([big, small])
    assert [solid_pieces(truth, join=0.01, seed=s)[1] for s in range(3)] == [1, 1, 1]
    fit = trimesh.util.concatenate([big, small.copy().apply_translation([0.0, 0.03, 0.0])])
    m = extra_pieces(fit, truth, join=0.01, sliver=0.008)
    assert (m["gt_pieces"], m["pieces"], m["extra_pieces"]) == (1, 2, 0)
    # a floater beside the big sphere is still extra: the big sphere's fit reaches its part
    loose = trimesh.creation.icosphere(2, radius=0.03).apply_translation([0.0, 0.36, 0.0])
    m = extra_pieces(trimesh.util.concatenate([fit, loose]), truth, join=0.01, sliver=0.008)
    assert (m["pieces"], m["extra_pieces"]) == (3, 1)
