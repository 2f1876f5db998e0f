"""`Shape.sdf`: the world-space field users query directly."""
import numpy as np
import torch

from ngc_gen.shape import Shape
from ngc_gen.shape.shape import OUTSIDE


def test_sdf_is_the_min_over_the_gcs_containing_each_point(module, gcs):
    shape = Shape(gcs, module.codes.weight[:3], module.decoder)
    body = gcs[0]
    q = np.concatenate([np.asarray(body.to_world(np.random.default_rng(0).uniform(
        [-1, -0.6, -0.6], [1, 0.6, 0.6], (2000, 3)))), [[5.0, 5.0, 5.0]]])
    got = shape.sdf(q)
    want = torch.full((len(q),), float("inf"))
    for j, g in enumerate(gcs):
        i = torch.from_numpy(np.flatnonzero(g.contains(q)))
        rel = torch.as_tensor(g.to_relative(q[i.numpy()]), dtype=torch.float32)
        want[i] = torch.minimum(want[i], shape.gc_sdf(j, rel).float())
    assert torch.isfinite(want[:-1]).all()            # every sample lies in the body GC
    torch.testing.assert_close(got[:-1], want[:-1], atol=1e-6, rtol=0)
    assert got[-1] == OUTSIDE                         # outside every GC
