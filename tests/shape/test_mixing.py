"""Part mixing (features blended along t, `Shape` mixes) and the smooth union extraction."""
import numpy as np
import pytest
import torch

from ngc_gen.edit import constant, linear, smoothstep, truncated_linear
from ngc_gen.extract import extract_mesh, per_gc_rows
from ngc_gen.shape import PartFeatures as PartMix
from ngc_gen.shape import Shape


def mixed_sdf_fn(decoder, codes, mixes=None):
    """The shape's per-GC field (GCs do not matter for gc_sdf: placeholders)."""
    from ..edit.conftest import GC_DICTS
    from ngc_gen.geometry import GeneralizedCylinder

    gc = GeneralizedCylinder.from_dict(GC_DICTS[0])
    return Shape([gc] * len(codes), codes, decoder, mixes=mixes).gc_sdf


def extract_smooth_union(gcs, fn, resolution, k):
    """The extractor's smooth union of a per-GC field (what `Shape.mesh` runs for smooth > 0)."""
    return extract_mesh(gcs, per_gc_rows(fn), resolution, smooth=k)


@pytest.fixture
def rel():
    g = torch.Generator().manual_seed(0)
    r = torch.rand(2000, 3, generator=g) * 2 - 1
    r[:, 0] *= 2  # u in [-2, 2]
    return r


def codes_of(module, shape):
    return module.codes.weight[3 * shape:3 * shape + 3].detach()


def test_unmixed_fn_is_the_decoder(module, rel):
    codes = codes_of(module, 0)
    fn = mixed_sdf_fn(module.decoder, codes)
    with torch.no_grad():
        for j in range(3):
            assert torch.equal(fn(j, rel), module.decoder(codes[j].expand(len(rel), -1), rel))


def test_weight_zero_keeps_a_and_replace_gives_b(module, rel):
    a, b = codes_of(module, 0), codes_of(module, 1)
    keep = mixed_sdf_fn(module.decoder, a, {1: PartMix(b[1], constant(0.0))})
    repl = mixed_sdf_fn(module.decoder, a, {1: PartMix(b[1], None)})  # replace
    plain_a, plain_b = mixed_sdf_fn(module.decoder, a), mixed_sdf_fn(module.decoder, b)
    assert torch.equal(keep(1, rel), plain_a(1, rel))
    assert torch.equal(repl(1, rel), plain_b(1, rel))
    assert torch.equal(repl(0, rel), plain_a(0, rel))  # other GCs untouched
    assert not torch.allclose(plain_a(1, rel), plain_b(1, rel))


@pytest.mark.parametrize("weight", [truncated_linear(0.3, 0.6), smoothstep(0.3, 0.6)])
def test_ramp_blends_between_the_parts_along_t(module, rel, weight):
    a, b = codes_of(module, 0), codes_of(module, 1)
    fn = mixed_sdf_fn(module.decoder, a, {0: PartMix(b[0], weight)})
    fa, fb = mixed_sdf_fn(module.decoder, a)(0, rel), mixed_sdf_fn(module.decoder, b)(0, rel)
    t = (rel[:, 0] + 1) / 2
    out = fn(0, rel)
    torch.testing.assert_close(out[t <= 0.3], fa[t <= 0.3], atol=1e-6, rtol=0)
    torch.testing.assert_close(out[t >= 0.6], fb[t >= 0.6], atol=1e-6, rtol=0)
    mid = (t > 0.35) & (t < 0.55)
    assert not torch.allclose(out[mid], fa[mid]) and not torch.allclose(out[mid], fb[mid])


def test_linear_blend_is_the_feature_lerp(module, rel):
    a, b = codes_of(module, 0), codes_of(module, 1)
    dec = module.decoder
    u = rel[:, 0]
    t = ((u + 1) / 2).clamp(0, 1)[:, None]
    with torch.no_grad():
        feats = (1 - t) * dec.features(a[2].expand(len(rel), -1), u) \
            + t * dec.features(b[2].expand(len(rel), -1), u)
        want = dec.sdf_from_features(rel, feats)
    got = mixed_sdf_fn(dec, a, {2: PartMix(b[2], linear())})(2, rel)
    torch.testing.assert_close(got, want, atol=1e-6, rtol=0)


def test_mix_checks_its_inputs(module):
    a = codes_of(module, 0)
    with pytest.raises(ValueError, match="GC index 5"):
        mixed_sdf_fn(module.decoder, a, {5: PartMix(a[0], constant(1.0))})
    with pytest.raises(ValueError, match="same network"):
        mixed_sdf_fn(module.decoder, a, {0: PartMix(torch.zeros(3), constant(1.0))})


def test_smooth_union_zero_width_is_the_hard_min(module, gcs):
    fn = mixed_sdf_fn(module.decoder, codes_of(module, 0))
    hard = extract_mesh(gcs, per_gc_rows(fn), 48).mesh
    same = extract_smooth_union(gcs, fn, 48, k=0.0).mesh
    assert np.array_equal(hard.vertices, same.vertices) and np.array_equal(hard.faces, same.faces)


def test_smooth_union_fills_the_seam_and_only_there(module, gcs):
    fn = mixed_sdf_fn(module.decoder, codes_of(module, 0))
    hard = extract_mesh(gcs, per_gc_rows(fn), 64)
    k = 0.1
    soft = extract_smooth_union(gcs, fn, 64, k=k).mesh
    assert soft.is_watertight
    # union only ever adds material, and only near the overlaps: a bounded volume gain
    assert hard.mesh.volume < soft.volume < 1.3 * hard.mesh.volume
    # far from the arm/tail joints the surfaces agree (points of the body's middle, x in 0..0.1
    # lies in the arm's region; -0.2..-0.1 only in the body)
    pick = lambda m: m.vertices[(m.vertices[:, 0] > -0.2) & (m.vertices[:, 0] < -0.1)]
    from scipy.spatial import cKDTree
    d, _ = cKDTree(pick(hard.mesh)).query(pick(soft))
    assert d.max() < 0.01


def test_smooth_union_rejects_negative_width(module, gcs):
    with pytest.raises(ValueError, match="smooth must be >= 0"):
        extract_smooth_union(gcs, mixed_sdf_fn(module.decoder, codes_of(module, 0)), 32, k=-1)
