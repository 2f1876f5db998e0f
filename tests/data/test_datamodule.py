"""Training rows and how often each is drawn (ngc_gen.data.datamodule)."""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.data.datamodule import PreparedDataModule, row_weights, shared_rows, training_rows
from ngc_gen.data.prepare import PrepareSettings, prepare_shape

SMALL = PrepareSettings.from_yaml(n_samples=4_000, coverage_samples=4_000)


def _two_gc_shape(sphere_file, write_yaml, gc_dict, tmp_path):
    path = write_yaml({"name": "two", "mesh": sphere_file.name,
                       "gcs": [gc_dict("left", -0.6, 0.1), gc_dict("right", -0.1, 0.6)]})
    return prepare_shape(path, SMALL, tmp_path / "cache")


def test_shared_rows_are_the_samples_in_two_gcs(sphere_file, write_yaml, gc_dict, tmp_path):
    shape = _two_gc_shape(sphere_file, write_yaml, gc_dict, tmp_path)
    ids, coords, _, _ = training_rows([shape, shape], "ngc")
    shared = shared_rows([shape, shape])
    assert shared.shape == ids.shape and 0 < shared.sum() < len(shared)
    gcs = shape.gcs()
    pts = shape.points[shape.pair_point].astype(np.float64)
    both = np.asarray(gcs[0].contains(pts)) & np.asarray(gcs[1].contains(pts))
    np.testing.assert_array_equal(shared.numpy(), np.concatenate([both, both]))


def test_junction_weight_draws_shared_rows_more_often(sphere_file, write_yaml, gc_dict, tmp_path):
    shape = _two_gc_shape(sphere_file, write_yaml, gc_dict, tmp_path)
    ids, _, _, _ = training_rows([shape], "ngc")
    shared = shared_rows([shape])
    assert row_weights(ids, 0.0, shared, 0.0) is None          # the default: uniform
    w = row_weights(ids, 0.0, shared, 3.0)
    np.testing.assert_allclose(w.numpy(), np.where(shared.numpy(), 4.0, 1.0))
    balanced = row_weights(ids, 1.0, shared, 3.0)               # composes with code_balance
    counts = torch.bincount(ids).double()
    np.testing.assert_allclose(balanced.numpy(), (w / counts[ids]).numpy())
    # an epoch of the data module draws shared rows in proportion: share s -> 4s / (1 + 3s)
    dm = PreparedDataModule([shape], batch_size=len(ids), junction_weight=3.0)
    _, coords, _ = dm.train_set[0]
    rel_shared = {tuple(r) for r in training_rows([shape], "ngc")[1][shared].numpy().tolist()}
    drawn = np.mean([tuple(r) in rel_shared for r in coords.numpy().tolist()])
    s = shared.double().mean().item()
    assert abs(drawn - 4 * s / (1 + 3 * s)) < 0.03


def test_blend_shares_split_each_sample_over_its_gcs(sphere_file, write_yaml, gc_dict, tmp_path):
    """With the blended union a batch carries each row's share of its sample: the shares of a
    sample's rows sum to 1, a sample one GC holds has share 1, and a row near its GC's boundary
    inside the other GC has less than the other GC's row."""
    from ngc_gen.data.datamodule import blend_shares
    from ngc_gen.geometry import GeneralizedCylinder

    shape = _two_gc_shape(sphere_file, write_yaml, gc_dict, tmp_path)
    shares = blend_shares([shape], 0.3).numpy().astype(np.float64)
    total = np.bincount(shape.pair_point, weights=shares, minlength=len(shape.points))
    paired = np.bincount(shape.pair_point, minlength=len(shape.points))
    np.testing.assert_allclose(total[paired > 0], 1.0, rtol=1e-5)
    single = paired[shape.pair_point] == 1
    np.testing.assert_allclose(shares[single], 1.0, rtol=1e-6)
    rho = np.sqrt(GeneralizedCylinder.relative_measure(shape.pair_rel.astype(np.float64)))
    deepest = np.full(len(shape.points), np.inf)
    np.minimum.at(deepest, shape.pair_point, rho)
    edge = ~single & (rho > 0.97) & (deepest[shape.pair_point] < 0.7)
    assert edge.any() and shares[edge].max() < 0.05
    dm = PreparedDataModule([shape], batch_size=64, blend=0.3)
    assert len(dm.train_set[0]) == 4
    assert len(PreparedDataModule([shape], batch_size=64).train_set[0]) == 3
