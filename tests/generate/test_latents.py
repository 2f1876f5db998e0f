"""Latent-space helpers of sample.py: per-shape seeds, lerp, slerp and interpolation paths."""
import math

import torch

import pytest

from ngc_gen.generate import latent_path, latent_seed, lerp, slerp


def test_latent_seeds_are_distinct_and_stable():
    seeds = {latent_seed(0, i) for i in range(100)} | {latent_seed(1, i) for i in range(100)}
    assert len(seeds) == 200
    assert latent_seed(3, 7) == latent_seed(3, 7)


def test_lerp_and_slerp_hit_both_ends_exactly():
    g = torch.Generator().manual_seed(0)
    a, b, c = (torch.randn(64, generator=g, dtype=torch.float64) for _ in range(3))
    al = torch.linspace(0, 1, 7, dtype=torch.float64)
    for path in (lerp(a, b, al), slerp(a, b, al), slerp(a, b, al, center=c)):
        assert path.shape == (7, 64)
        assert torch.equal(path[0], a) and torch.equal(path[-1], b)
    torch.testing.assert_close(lerp(a, b, al)[3], (a + b) / 2)


def test_slerp_follows_the_great_circle():
    """Unit vectors 90 degrees apart: the path stays on the unit circle at evenly spaced angles."""
    a, b = torch.tensor([1.0, 0.0], dtype=torch.float64), torch.tensor([0.0, 1.0],
                                                                       dtype=torch.float64)
    al = torch.linspace(0, 1, 5, dtype=torch.float64)
    p = slerp(a, b, al)
    torch.testing.assert_close(p.norm(dim=1), torch.ones(5, dtype=torch.float64))
    torch.testing.assert_close(torch.atan2(p[:, 1], p[:, 0]), al * math.pi / 2)
    # about a centre: the same circle shifted
    c = torch.tensor([3.0, -2.0], dtype=torch.float64)
    torch.testing.assert_close(slerp(a + c, b + c, al, center=c), p + c)
    # parallel vectors fall back to lerp
    torch.testing.assert_close(slerp(a, 2 * a, al), lerp(a, 2 * a, al))


def test_latent_path_ends_at_the_two_latents_in_their_dtype():
    g = torch.Generator().manual_seed(1)
    a, b = torch.randn(16, generator=g), torch.randn(16, generator=g)
    alphas, path = latent_path(a, b, 5)
    assert path.dtype == torch.float32 and torch.equal(path[0], a) and torch.equal(path[-1], b)
    assert alphas.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    torch.testing.assert_close(path[2], (a + b) / 2)
    _, arc = latent_path(a, b, 5, "slerp", center=torch.zeros(16))
    assert torch.equal(arc[0], a) and torch.equal(arc[-1], b)
    assert float(arc[2].norm()) > float(path[2].norm())  # the arc bulges out, the chord does not
    with pytest.raises(ValueError, match="lerp or slerp"):
        latent_path(a, b, 3, "cubic")
