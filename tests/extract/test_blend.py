"""The blended union (`ngc_gen.geometry.union`) on every extraction path: the fold by hand on
the reference grid, the sparse path equal to it, no step where a GC ends inside another, and a
shape's `sdf` the same field."""
import numpy as np
import pytest
import torch

from ngc_gen.extract import FieldCache, extract_mesh, per_gc_rows
from ngc_gen.geometry import GeneralizedCylinder, fade_weight
from ngc_gen.geometry.union import FLOOR, BlendAccumulator
from ngc_gen.shape import Shape
from tests.edit.conftest import GC_DICTS, make_module

from .conftest import grid_points, sphere_sdf, straight_gc, through_gcs


def same_mesh(a, b) -> bool:
    return np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def two_gcs():
    ga = straight_gc((-0.5, 0, 0), (0.5, 0, 0), 0.5, caps=(0.2, 0.2), name="x")
    gb = straight_gc((0, -0.5, 0), (0, 0.5, 0), 0.5, caps=(0.2, 0.2), name="y")
    return ga, gb


def test_fade_weight_is_one_deep_inside_and_floor_on_the_boundary():
    m = np.array([0.0, 0.5 ** 2, 0.75 ** 2, 0.9 ** 2, 1.0, 2.0])
    w = fade_weight(m, 0.25)
    assert w[0] == pytest.approx(1.0) and w[1] == pytest.approx(1.0)
    assert w[2] == pytest.approx(1.0) and 0 < w[3] < 1
    assert w[4] == pytest.approx(FLOOR) and w[5] == pytest.approx(FLOOR)
    wt = fade_weight(torch.from_numpy(m), 0.25)
    np.testing.assert_allclose(wt.numpy(), w, rtol=1e-6)
    with pytest.raises(Exception, match="blend width"):
        fade_weight(m, 0.0)


def test_soft_blend_averages_agreeing_gcs_and_keeps_the_smaller_of_disagreeing_ones():
    """k > 0: equal values stay that value, values apart by much more than k give about the
    smaller one (a thin part's own GC keeps its material), a GC on its boundary (weight FLOOR)
    counts only by what it undercuts the other by past k ln(1 / FLOOR), and k = 0 is the
    weighted mean."""
    deep, edge = 0.0, 1.0                     # measures: rho = 0 and rho = 1
    f1 = np.array([0.01, -0.02, 0.01, 0.01])
    f2 = np.array([0.01, 0.03, 0.03, -0.05])
    m2 = np.array([deep, deep, deep, edge])
    acc = BlendAccumulator(4, 0.25, k=0.002)
    acc.add(np.arange(4), f1, np.full(4, deep))
    acc.add(np.arange(4), f2, m2)
    out = acc.result()
    assert out[0] == pytest.approx(0.01, abs=1e-7)
    assert out[1] == pytest.approx(-0.02 + 0.002 * np.log(2), abs=1e-4)
    assert 0.01 < out[2] < 0.0115
    # on its boundary a GC far below the other is lifted by about k ln(1 / FLOOR): the step
    # where it ends shrinks by that much (and vanishes for disagreements under it)
    assert -0.05 + 0.9 * 0.002 * np.log(1 / FLOOR) < out[3] < 0.01
    mean = BlendAccumulator(4, 0.25)
    mean.add(np.arange(4), f1, np.full(4, deep))
    mean.add(np.arange(4), f2, np.full(4, deep))
    np.testing.assert_allclose(mean.result(), (f1 + f2) / 2, atol=1e-7)
    assert np.isinf(BlendAccumulator(2, 0.25, k=0.01).result()).all()   # held by no GC


@pytest.mark.parametrize("k", [0.0, 0.02])
def test_sparse_equals_the_reference_grid_with_the_soft_blend(k):
    ga, gb = two_gcs()
    fields = [sphere_sdf((0.15, 0.0, 0.0), 0.3), sphere_sdf((0.0, 0.15, 0.0), 0.33)]
    rows = per_gc_rows(through_gcs([ga, gb], fields))
    ref = extract_mesh([ga, gb], rows, 32, method="prefiltered", blend=0.3, blend_k=k)
    assert len(ref.mesh.faces) > 200
    assert same_mesh(extract_mesh([ga, gb], rows, 32, blend=0.3, blend_k=k).mesh, ref.mesh)


def test_blend_is_the_weighted_mean_in_gc_order_and_sparse_equals_it():
    ga, gb = two_gcs()
    fields = [sphere_sdf((0.15, 0.0, 0.0), 0.3), sphere_sdf((0.0, 0.15, 0.0), 0.33)]
    sdf_fn, R, width = through_gcs([ga, gb], fields), 32, 0.3
    ref = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, method="prefiltered", blend=width,
                       keep_values=True)
    pts = grid_points(R)
    num, den = np.zeros(len(pts)), np.zeros(len(pts))
    for j, gc in enumerate([ga, gb]):
        rel, m = gc.relative_inside(pts)
        inside = m <= 1.0
        v = sdf_fn(j, torch.from_numpy(rel[inside]).float()).numpy()
        w = fade_weight(m[inside].astype(np.float32), width)
        num[inside] += w * v
        den[inside] += w
    acc = np.where(den > 0, num / np.maximum(den, 1e-300), ref.stats["background"])
    np.testing.assert_allclose(ref.values.reshape(-1), acc, rtol=0, atol=1e-6)
    dense = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, method="dense", blend=width)
    assert same_mesh(dense.mesh, ref.mesh)
    sparse = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, blend=width)
    assert same_mesh(sparse.mesh, ref.mesh)
    with pytest.raises(ValueError, match="not both"):
        extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, blend=width, smooth=0.1)


def test_no_step_where_a_gc_ends_inside_another():
    """Two GCs whose fields disagree by a constant: the min steps by that constant where the
    second GC's boundary lies inside the first, the blend changes by at most FLOOR x it."""
    ga, gb = two_gcs()
    offset = 0.05
    fields = [lambda x: x[:, 2].double() - 0.1, lambda x: x[:, 2].double() - 0.1 + offset]
    sdf_fn = through_gcs([ga, gb], fields)
    # points along y at z = 0, x = 0: across gb's cap end at y = 0.7 while inside ga (radius 0.5)?
    # ga holds |y| <= 0.5 on x = 0; gb holds y up to 0.7: walk y over ga's boundary inside gb
    y = np.linspace(0.3, 0.6, 601)
    pts = np.stack([np.zeros_like(y), y, np.zeros_like(y)], 1)
    module_free = [Shape([ga, gb], torch.zeros(2, 1), None, blend=b) for b in (0.0, 0.3)]
    def rows(gc_index, rel):  # Shape.sdf's one call for all GCs' rows, here per GC's field
        out = torch.empty(len(rel), dtype=torch.float64)
        for j in range(2):
            m = gc_index == j
            out[m] = torch.as_tensor(sdf_fn(j, rel[m]), dtype=torch.float64)
        return out

    for shape in module_free:
        shape.rows = rows
    hard, soft = (s.sdf(pts).numpy() for s in module_free)
    assert np.abs(np.diff(hard)).max() >= 0.9 * offset          # the min's seam
    assert np.abs(np.diff(soft)).max() < 0.1 * offset            # the blend's ramp


def test_shape_blend_sdf_matches_its_mesh_and_edits_reuse_the_cache():
    module = make_module()
    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    shape = Shape(gcs, module.codes.weight[:3], module.decoder, blend=0.25)
    R = 64
    ref = shape.mesh(R, method="prefiltered", keep_values=True)
    pts = grid_points(R)
    vals = shape.sdf(pts).numpy()
    covered = np.isfinite(ref.values.reshape(-1)) & (vals != 1.0)
    np.testing.assert_allclose(vals[covered], ref.values.reshape(-1)[covered], atol=2e-5)
    first = shape.mesh(R)
    assert same_mesh(first.mesh, ref.mesh)
    moved = shape.replaced(gcs=[gcs[0], gcs[1], gcs[2].transformed(np.eye(3),
                                                                   np.array([0.02, 0, 0]))])
    again = moved.mesh(R)
    assert again.stats["cache_hits"] == 2 and again.stats["cache_misses"] == 1
    assert same_mesh(again.mesh, moved.mesh(R, method="prefiltered").mesh)
