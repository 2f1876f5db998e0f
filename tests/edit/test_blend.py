import pytest
import torch

from ngc_gen.edit import (EditError, blend_features, blend_weight, constant, linear, smoothstep,
                          truncated_linear)
from ngc_gen.geometry import GeometryError, smooth_min, smooth_min_all

T = torch.linspace(-0.2, 1.2, 14001, dtype=torch.float64)
WEIGHTS = [linear(), truncated_linear(0.3, 0.6), smoothstep(0.2, 0.7)]


@pytest.mark.parametrize("fn", WEIGHTS, ids=repr)
def test_weights_run_from_0_to_1_monotone_and_continuous(fn):
    w = fn(T)
    assert w.shape == T.shape and w.dtype == T.dtype
    assert fn(torch.tensor([0.0])).item() == 0.0 and fn(torch.tensor([1.0])).item() == 1.0
    assert w.min() >= 0 and w.max() <= 1
    assert torch.all(w[1:] >= w[:-1])  # monotone
    step = (T[1] - T[0]).item()
    # no jumps: the steepest ramp here has slope 1/0.3
    assert (w[1:] - w[:-1]).abs().max() <= 3.5 * step


def test_truncated_linear_and_smoothstep_values():
    tl = truncated_linear(0.3, 0.6)
    torch.testing.assert_close(tl(torch.tensor([0.0, 0.3, 0.45, 0.6, 0.9])),
                               torch.tensor([0.0, 0.0, 0.5, 1.0, 1.0]))
    ss = smoothstep(0.2, 0.7)
    torch.testing.assert_close(ss(torch.tensor([0.2, 0.45, 0.7])), torch.tensor([0.0, 0.5, 1.0]))
    # C1: zero slope at both ends of the ramp
    h = 1e-6
    for t0 in (0.2, 0.7):
        x = torch.tensor([t0 - h, t0 + h], dtype=torch.float64)
        assert (ss(x)[1] - ss(x)[0]).abs() / (2 * h) < 1e-5
    torch.testing.assert_close(constant(0.25)(T), torch.full_like(T, 0.25))
    assert linear()(0.4).item() == pytest.approx(0.4)  # plain floats work too


def test_blend_features_endpoints_and_shapes():
    fa, fb = torch.randn(5, 8), torch.randn(5, 8)
    t = torch.tensor([0.0, 0.1, 0.45, 0.9, 1.0])
    out = blend_features(fa, fb, t, truncated_linear(0.3, 0.6))
    assert out.shape == (5, 8)
    torch.testing.assert_close(out[:2], fa[:2])
    torch.testing.assert_close(out[3:], fb[3:])
    torch.testing.assert_close(out[2], 0.5 * (fa[2] + fb[2]))
    # per-GC end features (D,) broadcast against (N,) t
    out = blend_features(torch.zeros(4), torch.ones(4), torch.tensor([0.0, 0.5, 1.0]), linear())
    torch.testing.assert_close(out, torch.tensor([[0.0] * 4, [0.5] * 4, [1.0] * 4]))


def test_blend_registry_and_errors():
    assert blend_weight("truncated_linear", t0=0.1, t1=0.2) == truncated_linear(0.1, 0.2)
    with pytest.raises(EditError, match="unknown blend"):
        blend_weight("cosine")
    with pytest.raises(EditError, match="bad parameters"):
        blend_weight("smoothstep", t0=0.1)
    for bad in ((0.6, 0.3), (0.2, 0.2), (-0.1, 0.5), (0.1, float("nan"))):
        with pytest.raises(EditError, match="t0 < t1"):
            truncated_linear(*bad)
    with pytest.raises(EditError, match=r"\[0, 1\]"):
        constant(1.5)


def test_smooth_min_is_a_smooth_lower_bound_of_min():
    g = torch.Generator().manual_seed(0)
    a, b = torch.randn(10000, generator=g, dtype=torch.float64), torch.randn(
        10000, generator=g, dtype=torch.float64)
    m = torch.minimum(a, b)
    for k in (0.5, 0.1, 0.01):
        s = smooth_min(a, b, k)
        assert torch.all(s <= m + 1e-15) and torch.all(s >= m - k / 4 - 1e-15)
        far = (a - b).abs() >= k
        torch.testing.assert_close(s[far], m[far])  # exact away from the seam
    assert (smooth_min(a, b, 1e-6) - m).abs().max() <= 1e-6 / 4 + 1e-15  # -> min as k -> 0
    torch.testing.assert_close(smooth_min(a, b, 0.0), m)
    # continuous across the seam a = b
    x = torch.linspace(-1, 1, 20001, dtype=torch.float64)
    s = smooth_min(x, torch.zeros_like(x), 0.3)
    assert (s[1:] - s[:-1]).abs().max() <= (x[1] - x[0]) + 1e-12
    with pytest.raises(GeometryError, match="k must be >= 0"):
        smooth_min(a, b, -1.0)


def test_smooth_min_all_folds_columns():
    d = torch.tensor([[0.3, 1.0, 2.0], [-0.5, 0.4, 0.45]], dtype=torch.float64)
    torch.testing.assert_close(smooth_min_all(d, 0.0), d.min(1).values)
    s = smooth_min_all(d, 0.1)
    assert s[0] == pytest.approx(0.3) and s[1] == pytest.approx(-0.5)
