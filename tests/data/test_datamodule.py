"""Training rows and how often each is drawn (ngc_gen.data.datamodule)."""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.data.datamodule import PreparedDataModule, row_weights, shared_rows, training_rows
from ngc_gen.data.prepare import PrepareSettings, prepare_shape

SMALL = PrepareSettings(n_samples=4_000, coverage_samples=4_000)


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
