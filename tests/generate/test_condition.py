"""Generation from a skeleton (ngc_gen.generate.condition): guided EDM sampling toward target
GCs, on a small shape-latent + diffusion model trained in the fixture on creature GCs (no
meshes: the shape decoder learns the GC parameters of 32 procedural creatures)."""
import json

import numpy as np
import pytest
import torch

from ngc_gen.data.procedural.creatures import CREATURE_TEMPLATE, KEY_TS, _enclosing_gc, sample_parts
from ngc_gen.data.errors import DataError
from ngc_gen.generate import ShapeGenerator
from ngc_gen.generate.condition import (condition_from_gcs, conditional_latents, gc_error,
                                        load_condition, replace_gcs)
from ngc_gen.generate.shapes import decode_shapes
from ngc_gen.lit.diffusion import LatentDiffusion
from ngc_gen.lit.shape_latent import ShapeLatentModule
from ngc_gen.models.shape_decoder import GCSlot, GCTemplate

pytestmark = pytest.mark.usefixtures("single_thread")

N_TRAIN, DIM = 32, 128
LEGS = ("leg_fl", "leg_fr", "leg_bl", "leg_br")
GUIDE = dict(project_steps=0, sampler={"steps": 8})   # 15 denoiser calls a sample: fast


def creature_gcs(seed: int) -> list[dict]:
    """The ground-truth GC dicts of procedural creature `seed` (no mesh is built)."""
    return json.loads(json.dumps([_enclosing_gc(p, 0.01) for p in sample_parts(seed)],
                                 default=float))             # plain floats (YAML-safe)


def training_gcs(i: int) -> list[dict]:
    """Creature i with the legs of creature 500 + i: legs independent of the rest, so a model
    of these shapes must leave the rest free when the legs are given."""
    legs = {d["name"]: d for d in creature_gcs(500 + i) if d["name"] in LEGS}
    return [legs.get(d["name"], d) for d in creature_gcs(i)]


@pytest.fixture(scope="module")
def gen():
    """A ShapeGenerator whose shape decoder maps 128-d latents to the GCs of 32 creatures (param
    loss only, 300 steps) and whose EDM is trained briefly (200 steps) on those latents."""
    torch.manual_seed(0)
    template = GCTemplate([GCSlot(p.name, p.degree, p.up, KEY_TS) for p in CREATURE_TEMPLATE])
    vectors = np.stack([template.vector(training_gcs(i)) for i in range(N_TRAIN)])
    from ..lit.test_shape_latent import decoder_sizes

    sl = ShapeLatentModule(N_TRAIN, template.to_dict(), decoder_sizes("small"), latent_dim=DIM,
                           shape_decoder={"hidden": 64, "layers": 2},
                           meta={"shapes": [{"name": f"c{i}"} for i in range(N_TRAIN)]})
    sl.set_targets(vectors)
    sd = sl.shape_decoder
    opt = torch.optim.Adam(list(sd.parameters()) + list(sl.latents.parameters()), lr=1e-2)
    target = sd.normalise(sl.target_params).float()
    for _ in range(300):
        opt.zero_grad()
        z, _ = sd(sl.latents.weight)
        ((z - target)[:, sd.varying] ** 2).mean().backward()
        opt.step()
    sl.eval()
    diff = LatentDiffusion(DIM, denoiser={"width": 64, "depth": 2})
    latents = sl.latents.weight.detach()
    diff.fit_standardisation(latents)
    opt = torch.optim.Adam(diff.net.parameters(), lr=2e-3)
    g = torch.Generator().manual_seed(0)
    y = diff.standardise(latents)
    for _ in range(200):
        opt.zero_grad()
        diff.loss_fn(diff.net, y, generator=g).mean().backward()
        opt.step()
    diff.update_ema(0.0)
    return ShapeGenerator(sl.eval(), diff.eval(), "fixture")


@pytest.fixture(scope="module")
def target(gen):
    """GCs of a creature the model never saw."""
    return creature_gcs(1000)


@pytest.fixture(scope="module")
def drawn(gen):
    """GCs the model can produce exactly: those of a generated shape (as sample.py writes them,
    the YAML a user edits and conditions on)."""
    return gen.shape_latent.gc_dicts(gen.sample_latents([0], seed=99))[0]


def test_strength_zero_is_the_unconditional_sampler(gen, target):
    cond = condition_from_gcs(gen.shape_latent.template, target)
    plain = gen.sample_latents(range(3), seed=5)          # sample.py mode=generate's latents
    guided = conditional_latents(gen, cond, range(3), seed=5, strength=0.0, project_steps=2)
    assert torch.equal(guided, plain)
    weak = conditional_latents(gen, cond, [1], seed=5, strength=0.1, project_steps=0)
    assert not torch.equal(weak[0], plain[1])


def test_gc_error_falls_as_strength_rises(gen, drawn):
    cond = condition_from_gcs(gen.shape_latent.template, drawn)
    sd = gen.shape_latent.shape_decoder
    errs = [float(gc_error(sd, conditional_latents(gen, cond, range(3), seed=0, strength=w,
                                                   **GUIDE), cond).mean())
            for w in (0.0, 1.0, 3.0, 10.0)]
    assert all(a > b for a, b in zip(errs, errs[1:])), errs
    assert errs[0] > 0.5 and errs[3] < 0.1, errs  # std units; measured 1.07, 0.42, 0.13, 0.06


def spread(gen, latents, names) -> float:
    """Mean over the GCs' parameters of their std across samples (std units)."""
    z = gen.shape_latent.shape_decoder(latents)[0].detach()
    cols = [z[:, sl] for name, _, sl in gen.shape_latent.template.fields() if name in names]
    return float(torch.cat(cols, 1).std(0).mean())


def test_partial_condition_keeps_the_other_gcs_varied(gen, drawn):
    template = gen.shape_latent.template
    cond = condition_from_gcs(template, [d for d in drawn if d["name"] in LEGS])
    assert cond.names == LEGS
    sd = gen.shape_latent.shape_decoder
    plain = gen.sample_latents(range(6), seed=1, steps=8)
    guided = conditional_latents(gen, cond, range(6), seed=1, strength=10.0, **GUIDE)
    assert float(gc_error(sd, guided, cond).max()) < 0.2 * float(gc_error(sd, plain, cond).min())
    others = [name for name in template.names if name not in LEGS]
    # the legs are pinned, the other GCs still vary from sample to sample (measured: legs 0.06,
    # others 0.21 std; unconditioned 0.6 and 0.8)
    assert spread(gen, guided, LEGS) < 0.5 * spread(gen, guided, others)
    assert spread(gen, guided, others) > 0.15 * spread(gen, plain, others)


def test_replace_takes_the_target_gcs_and_keeps_the_codes(gen, target):
    template = gen.shape_latent.template
    cond = condition_from_gcs(template, [d for d in target if d["name"] in LEGS])
    z = conditional_latents(gen, cond, [0], seed=0, strength=10.0, **GUIDE)
    shape = decode_shapes(gen.shape_latent, z, ["s"])[0]
    out = replace_gcs(shape.gc_dicts(), cond)
    assert [d["name"] for d in out] == template.names
    for d, decoded in zip(out, shape.gc_dicts()):
        want = next((t for t in target if t["name"] == d["name"]), None)
        if d["name"] in LEGS:
            assert d["curve"]["points"] == want["curve"]["points"]
            assert [k["radii"] for k in d["keys"]] == [k["radii"] for k in want["keys"]]
            assert d["caps"] == want["caps"] and d["up"] == list(want["up"])
        else:
            assert d == decoded


def with_points(d: dict, points) -> dict:
    return {**d, "curve": {"type": "bezier", "points": points}}


def with_keys(d: dict, **values) -> dict:
    return {**d, "keys": [{**k, **values} for k in d["keys"]]}


@pytest.mark.parametrize("bad, match", [
    (lambda gcs: [{**gcs[0], "name": "wing"}], "no GC named 'wing'"),
    (lambda gcs: [with_points(gcs[1], gcs[1]["curve"]["points"] + [[0.1, 0.2, 0.3]])],
     "curve degree 3.*template's is 2"),
    (lambda gcs: [with_points(gcs[2], [[float("nan"), 0, 0]] + gcs[2]["curve"]["points"][1:])],
     r"curve\.points\[0\]\[0\]': must be finite, not nan"),
    (lambda gcs: [with_keys(gcs[3], twist=float("inf"))], r"twist': must be finite, not inf"),
    (lambda gcs: [with_keys(gcs[4], radii=[float("nan"), 0.1])], "radii"),
    (lambda gcs: [{**gcs[0], "keys": gcs[0]["keys"][:3]}], "key t's"),
    (lambda gcs: [gcs[0], gcs[0]], "given twice"),
    (lambda gcs: [], "non-empty list"),
])
def test_bad_conditions_are_clear_errors(gen, target, bad, match):
    with pytest.raises(DataError, match=match):
        condition_from_gcs(gen.shape_latent.template, bad(target))


def test_condition_files(gen, target, tmp_path, write_yaml):
    import yaml

    template = gen.shape_latent.template
    path = write_yaml({"name": "drawn", "mesh": "none.ply", "gcs": target[:2]}, "drawn.yaml")
    cond = load_condition(path, template)
    assert cond.names == ("torso", "neck") and int(cond.mask.sum()) == template.slots[0].size \
        + template.slots[1].size
    bad = {"name": "drawn", "gcs": [{**target[0], "name": "wing"}]}
    with pytest.raises(DataError, match=r"drawn2.yaml: GC 'wing'.*Fix: use names"):
        load_condition(write_yaml(bad, "drawn2.yaml"), template)
    (tmp_path / "broken.yaml").write_text("gcs: [\n")
    with pytest.raises(DataError, match="not a readable YAML"):
        load_condition(tmp_path / "broken.yaml", template)
    with pytest.raises(DataError, match="not found"):
        load_condition(tmp_path / "missing.yaml", template)
    assert yaml.safe_load(path.read_text())["gcs"][0]["name"] == "torso"


def test_a_re_centred_sample_file_conditions_in_the_decoder_frame(gen, drawn, tmp_path):
    """sample.py writes a generated shape's GCs re-centred and re-scaled (normalise=true) with
    the similarity as `decoder_frame`; conditioning on that file must target the GCs the
    decoder produced, not their normalised copy (which sits ~100 std away on near-constant
    parameters)."""
    from ngc_gen.data.annotations import similar_gc_dict
    from ngc_gen.generate.shapes import annotation_yaml

    template = gen.shape_latent.template
    center, scale = np.array([0.05, -0.02, 0.1]), 1.3
    moved = [similar_gc_dict(g, center, scale) for g in drawn]
    path = tmp_path / "sample_000.yaml"
    path.write_text(annotation_yaml("sample_000", "sample_000.ply", moved, 0.8, (center, scale)))
    got = load_condition(path, template)
    want = condition_from_gcs(template, drawn)
    assert torch.allclose(got.target, want.target, atol=1e-5)
    z = gen.sample_latents([0], seed=99)
    assert float(gc_error(gen.shape_latent.shape_decoder, z, got)[0]) < 1e-3
    path.write_text(annotation_yaml("sample_000", "sample_000.ply", moved, 0.8))  # no frame
    assert not torch.allclose(load_condition(path, template).target, want.target, atol=1e-3)


def test_guidance_works_on_principal_axes(gen):
    """With diffusion.standardise=pca the sampler and the guidance work on fewer coordinates
    than the latent has: GCs a sample of that model has are still met as strength rises."""
    torch.manual_seed(0)
    latents = gen.shape_latent.latents.weight.detach()
    diff = LatentDiffusion(DIM, denoiser={"width": 64, "depth": 2}, standardise="pca",
                           pca_variance=0.99)
    diff.fit_standardisation(latents)
    assert diff.space_dim < N_TRAIN
    opt = torch.optim.Adam(diff.net.parameters(), lr=2e-3)
    g, y = torch.Generator().manual_seed(0), diff.standardise(latents)
    for _ in range(200):
        opt.zero_grad()
        diff.loss_fn(diff.net, y, generator=g).mean().backward()
        opt.step()
    diff.update_ema(0.0)
    pca = ShapeGenerator(gen.shape_latent, diff.eval(), "fixture-pca")
    drawn = pca.shape_latent.gc_dicts(pca.sample_latents([0], seed=99))[0]
    cond = condition_from_gcs(pca.shape_latent.template, drawn)
    sd = pca.shape_latent.shape_decoder
    errs = [float(gc_error(sd, conditional_latents(pca, cond, range(3), seed=0, strength=w,
                                                   **GUIDE), cond).mean())
            for w in (0.0, 3.0, 10.0)]
    assert errs[0] > errs[1] > errs[2] and errs[2] < 0.1, errs
