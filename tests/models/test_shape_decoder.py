"""Shape decoder: the GC template's parameter vector round trip, template checks, and decoded
GCs that are valid (positive radii and caps, non-degenerate curves) for any latent."""
import copy

import numpy as np
import pytest
import torch

from ngc_gen.data.procedural.creatures import CREATURE_TEMPLATE, KEY_TS, make_creature
from ngc_gen.data.errors import DataError
from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.models.shape_decoder import GCTemplate, ShapeDecoder, param_errors

SEEDS = (11, 12, 13, 14, 15)


pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture(scope="module")
def creature_gcs():
    """GC dicts of a few creatures (coarse meshes: only the annotations are used)."""
    return [make_creature(s, resolution=64, check_samples=0)[1]["gcs"] for s in SEEDS]


@pytest.fixture(scope="module")
def template(creature_gcs):
    return GCTemplate.from_gcs(creature_gcs[0])


def test_template_is_the_creature_template(template):
    assert template.names == [p.name for p in CREATURE_TEMPLATE]
    for slot, part in zip(template.slots, CREATURE_TEMPLATE):
        assert slot.degree == part.degree and slot.up == part.up and slot.key_ts == KEY_TS
    # per GC: (degree + 1) control points, 5 keys x (2 radii + twist), 2 caps
    assert template.size == sum(3 * (p.degree + 1) + 5 * 3 + 2 for p in CREATURE_TEMPLATE)
    assert GCTemplate.from_dict(template.to_dict()).to_dict() == template.to_dict()


def test_parameter_vector_round_trip(template, creature_gcs):
    for gcs in creature_gcs:
        v = template.vector(gcs)
        back = template.gc_dicts(v)
        np.testing.assert_allclose(template.vector(back), v, rtol=0, atol=1e-12)
        for d, b in zip(gcs, back):
            assert b["name"] == d["name"] and b["up"] == d["up"]
            np.testing.assert_allclose(b["curve"]["points"], d["curve"]["points"], atol=1e-12)
            np.testing.assert_allclose([k["radii"] for k in b["keys"]],
                                       [k["radii"] for k in d["keys"]], rtol=1e-12)
            np.testing.assert_allclose([k["twist"] for k in b["keys"]],
                                       [k["twist"] for k in d["keys"]], atol=1e-12)
            assert [k["t"] for k in b["keys"]] == [k["t"] for k in d["keys"]]
            np.testing.assert_allclose(b["caps"], d["caps"], rtol=1e-12)
    # torch input, and fields cover the vector exactly once
    v = torch.as_tensor(template.vector(creature_gcs[1]))
    assert template.gc_dicts(v) == template.gc_dicts(v.numpy())
    covered = np.zeros(template.size, int)
    for _, _, sl in template.fields():
        covered[sl] += 1
    assert (covered == 1).all()


@pytest.mark.parametrize("change, field", [
    (lambda g: g.reverse(), "name"),
    (lambda g: g[0]["curve"]["points"].pop(), "curve.points"),
    (lambda g: g[2].update(up=[1.0, 0.0, 0.0]), "up"),
    (lambda g: g[3]["keys"].pop(), "keys"),
    (lambda g: g[1].update(reparam={"t": [0, 1], "arc": [0, 1]}), "reparam"),
    (lambda g: g.pop(), None),
])
def test_template_mismatch_names_shape_gc_and_field(template, creature_gcs, change, field):
    gcs = copy.deepcopy(creature_gcs[1])
    change(gcs)
    with pytest.raises(DataError) as e:
        template.vector(gcs, where="shape creature_x")
    assert "creature_x" in str(e.value) and "Fix:" in str(e.value)
    if field is not None:
        assert e.value.field == field and e.value.gc is not None


def test_up_vectors_equal_up_to_rounding_are_one_template(template, creature_gcs):
    """Rig GCs turned into the template's frame carry up vectors a few 1e-6 off the template's
    (0 A.D. animals facing -z): the same up, not a refusal."""
    gcs = copy.deepcopy(creature_gcs[1])
    up = np.asarray(gcs[2].get("up") or (0.0, 0.0, 1.0), float)
    gcs[2]["up"] = (up + [2e-6, -2e-6, 1e-6]).tolist()
    assert template.vector(gcs).shape == (template.size,)
    gcs[2]["up"] = (up + [3e-3, 0.0, 0.0]).tolist()
    with pytest.raises(DataError, match="up"):
        template.vector(gcs)


@pytest.fixture(scope="module", params=[True, False], ids=["explicit", "mlp_head"])
def decoder(template, creature_gcs, request):
    torch.manual_seed(0)
    dec = ShapeDecoder(32, template.size, template.n_gcs, code_dim=16, hidden=64,
                       explicit=request.param)
    dec.set_param_stats(np.stack([template.vector(g) for g in creature_gcs]))
    with torch.no_grad():  # untrained heads start at the mean: randomise them hard
        for p in dec.parameters():
            p.normal_(0.0, 1.0)
    return dec


@pytest.mark.parametrize("scale", [0.3, 3.0, 1000.0])
def test_decoded_gcs_are_valid_for_random_latents(template, decoder, scale):
    s = torch.randn(6, decoder.in_dim, generator=torch.Generator().manual_seed(int(scale))) * scale
    with torch.no_grad():
        theta, codes = decoder.decode(s)
    assert codes.shape == (6, template.n_gcs, 16) and torch.isfinite(codes).all()
    assert torch.isfinite(theta).all()
    z = decoder.normalise(theta)
    assert float(z.abs().max()) <= decoder.bound + 1e-4        # within bound std of the mean
    for t in theta:
        for d in template.gc_dicts(t):
            gc = GeneralizedCylinder.from_dict(d)               # raises on any invalid field
            assert gc.length > 1e-3
            assert min(min(k.radii) for k in gc.keys) > 0 and min(gc.caps) > 0
            assert np.isfinite(gc.bounds()[0]).all()


def test_constant_parameters_decode_exactly(template, decoder, creature_gcs):
    """Parameters that never vary in the data (the y of the torso on the symmetry plane, the
    twist of untwisted parts) are held at their value for every latent."""
    V = np.stack([template.vector(g) for g in creature_gcs])
    const = ~decoder.varying.numpy()
    assert const.any() and decoder.varying.any()
    with torch.no_grad():
        theta, _ = decoder.decode(torch.randn(8, decoder.in_dim) * 10)
    np.testing.assert_allclose(theta.numpy()[:, const], np.broadcast_to(V[0, const],
                                                                        (8, const.sum())),
                               atol=1e-6)
    assert decoder.normalise(torch.as_tensor(V, dtype=torch.float32))[:, const].abs().max() == 0


def test_explicit_latents_hold_their_gcs_exactly(template, creature_gcs):
    """An explicit latent [GC parameters in std units, free entries] decodes to exactly those
    GCs whatever its free entries, and its codes depend on both parts."""
    torch.manual_seed(0)
    dec = ShapeDecoder(8, template.size, template.n_gcs, code_dim=16, hidden=64, explicit=True)
    V = torch.as_tensor(np.stack([template.vector(g) for g in creature_gcs]))
    dec.set_param_stats(V)
    z = dec.gc_part(dec.normalise(V.float()))
    free = torch.randn(len(V), 8)
    with torch.no_grad():
        theta, codes = dec.decode(torch.cat([z, free], 1))
        _, codes_free = dec.decode(torch.cat([z, free + 1.0], 1))
        _, codes_gcs = dec.decode(torch.cat([z.roll(1, 0), free], 1))
    np.testing.assert_allclose(theta.numpy(), V.numpy(), atol=1e-5)
    assert not torch.allclose(codes, codes_free) and not torch.allclose(codes, codes_gcs)
    assert dec.in_dim == 8 + template.size


def test_param_errors_are_zero_for_identical_vectors(template, creature_gcs):
    V = np.stack([template.vector(g) for g in creature_gcs])
    e = param_errors(template, V, V)
    assert all(v == pytest.approx(0.0, abs=1e-12) for v in e.values())
    W = V.copy()
    W[:, template.fields()[0][2]] += 0.01       # shift every torso control point's x, y, z
    assert param_errors(template, W, V)["point_max"] == pytest.approx(0.01 * np.sqrt(3))
