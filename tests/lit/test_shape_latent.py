"""Shape-latent auto-decoder: the loss falls on a few creatures, the checkpoint rebuilds the
module exactly, and wrong files are clear errors."""
import warnings

import lightning as L
import numpy as np
import pytest
import torch
import yaml

from ngc_gen.data.procedural.creatures import make_creature
from ngc_gen.data.datamodule import PreparedDataModule
from ngc_gen.data.errors import DataError
from ngc_gen.data.prepare import PrepareSettings, prepare_shape
from ngc_gen.lit.shape_latent import ShapeLatentModule
from ngc_gen.app.stages.train_shape_latent import template_and_targets

from ..helpers import compose_config


pytestmark = pytest.mark.usefixtures("single_thread")


def decoder_sizes(model: str) -> dict:
    """The NGC decoder sizes of conf/model/<model>.yaml."""
    d = dict(compose_config(overrides=[f"model={model}"]).model.decoder)
    d.pop("_target_")
    return d


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """Three creatures (coarse meshes), 4000 samples each."""
    d = tmp_path_factory.mktemp("creatures")
    out = []
    for seed in (21, 22, 23):
        mesh, ann = make_creature(seed, resolution=64, check_samples=0, name=f"c{seed}")
        mesh.export(d / ann["mesh"])
        (d / f"c{seed}.yaml").write_text(yaml.safe_dump(ann, sort_keys=False))
        out.append(prepare_shape(d / f"c{seed}.yaml",
                                 PrepareSettings.from_yaml(n_samples=4000, coverage_samples=4000,
                                                 min_coverage=0.99)))
    return out


def make_module(prepared, **kw):
    template, vectors = template_and_targets(prepared)
    meta = {"shapes": [{"name": s.name, "annotation_yaml": s.annotation_yaml} for s in prepared]}
    m = ShapeLatentModule(len(prepared), template.to_dict(), decoder_sizes("small"), latent_dim=32,
                          shape_decoder={"hidden": 64}, meta=meta, **kw)
    m.set_targets(vectors)
    return m


def mean_losses(module, dm, batches=4):
    ds = dm.train_set
    ds.set_epoch(999)
    with torch.no_grad():
        rows = [module.losses(*ds[i]) for i in range(batches)]
    return {k: float(np.mean([float(r[k]) for r in rows])) for k in rows[0]}


def test_loss_decreases_on_three_creatures(prepared):
    torch.manual_seed(0)
    module = make_module(prepared, lr=3e-3, latent_lr=3e-3)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=1024, seed=0)
    before = mean_losses(module, dm)
    opt = module.configure_optimizers()
    ds = dm.train_set
    for step in range(30):
        ds.set_epoch(step)
        loss = module.losses(*ds[0])["loss"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    after = mean_losses(module, dm)
    assert after["loss"] < 0.5 * before["loss"], (before, after)
    assert after["l1"] < before["l1"] and after["param"] < 0.5 * before["param"], (before, after)


def test_explicit_latents_keep_their_gcs_through_training(prepared):
    """Explicit latents: each latent's GC entries are its shape's annotated parameters before
    and after training (they get no update, only the free entries and the networks learn), so
    every training latent decodes to its own GCs."""
    torch.manual_seed(0)
    module = make_module(prepared, lr=3e-3, latent_lr=3e-2, latent_noise=0.25)
    assert module.shape_decoder.explicit is False  # a bare dict is a pre-explicit record
    module = ShapeLatentModule(
        len(prepared), module.template.to_dict(), decoder_sizes("small"), latent_dim=32,
        shape_decoder={"hidden": 64, "explicit": True}, lr=3e-3, latent_lr=3e-2,
        latent_noise=0.25, meta=module.hparams.meta)
    module.set_targets(module.target_params.new_tensor(template_and_targets(prepared)[1]))
    P = module.n_fixed
    assert P == module.template.size and module.latents.weight.shape[1] == P + 32
    sd = module.shape_decoder
    expected = sd.gc_part(sd.normalise(module.target_params.float()))
    before = module.latents.weight.detach().clone()
    assert torch.allclose(before[:, :P], expected)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=1024, seed=0)
    opt = module.configure_optimizers()
    module.train()
    for step in range(10):
        dm.train_set.set_epoch(step)
        loss = module.losses(*dm.train_set[0])["loss"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    after = module.latents.weight.detach()
    assert torch.equal(after[:, :P], before[:, :P])
    assert not torch.allclose(after[:, P:], before[:, P:])
    with torch.no_grad():
        theta, _ = module.decode(after)
    np.testing.assert_allclose(theta.numpy(), module.target_params.numpy(), atol=1e-5)


def test_rows_map_to_shape_and_gc(prepared):
    """Global GC ids from the fit data module are shape * K + gc for a shared template."""
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=512)
    assert dm.n_codes == 10 * len(prepared)
    ids = dm.train_set.ids
    counts = np.bincount(ids.numpy() // 10, minlength=3)
    assert (counts == [len(s.pair_gc) for s in prepared]).all()


def test_checkpoint_round_trip_and_wrong_files(prepared, tmp_path):
    module = make_module(prepared)
    dm = PreparedDataModule(prepared, mode="ngc", batch_size=2048, seed=0)
    tr = L.Trainer(max_steps=3, accelerator="cpu", logger=False, enable_checkpointing=False,
                   enable_progress_bar=False, enable_model_summary=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tr.fit(module, datamodule=dm)
    (tmp_path / "run/checkpoints").mkdir(parents=True)
    tr.save_checkpoint(tmp_path / "run/checkpoints/last.ckpt")
    loaded = ShapeLatentModule.from_checkpoint(tmp_path / "run")   # a run directory works
    assert loaded.names == [s.name for s in prepared]
    s = module.latents.weight.detach()
    theta_a, codes_a = module.eval().decode(s)
    theta_b, codes_b = loaded.decode(loaded.latents.weight)
    assert torch.equal(theta_a, theta_b) and torch.equal(codes_a, codes_b)
    assert torch.equal(loaded.target_params, module.target_params)
    gcs = loaded.gc_dicts(s[:1])[0]
    assert [g["name"] for g in gcs] == loaded.template.names

    with pytest.raises(DataError, match="does not exist"):
        ShapeLatentModule.from_checkpoint(tmp_path / "missing")
    with pytest.raises(DataError, match="holds no checkpoints/last.ckpt"):
        ShapeLatentModule.from_checkpoint(tmp_path)
    wrong = tmp_path / "wrong.ckpt"
    torch.save({"hyper_parameters": {"checkpoint_kind": "ngc_gen.diffusion"}}, wrong)
    with pytest.raises(DataError, match="not a shape-latent checkpoint"):
        ShapeLatentModule.from_checkpoint(wrong)
    junk = tmp_path / "junk.ckpt"
    junk.write_text("not a checkpoint")
    with pytest.raises(DataError, match="not a loadable checkpoint"):
        ShapeLatentModule.from_checkpoint(junk)


def test_shapes_without_a_shared_template_are_refused(prepared):
    bad = prepared[1]
    d = yaml.safe_load(bad.annotation_yaml)
    d["gcs"] = d["gcs"][:-1]
    broken = type(bad)(**{**bad.__dict__, "annotation_yaml": yaml.safe_dump(d)})
    with pytest.raises(DataError, match=f"shape {bad.name}"):
        template_and_targets([prepared[0], broken])


def test_ngc_decoder_can_start_from_a_fit_checkpoint(prepared, tmp_path):
    from ngc_gen.lit.autodecoder import AutoDecoder
    from ngc_gen.app.stages.train_shape_latent import init_ngc_from_fit

    module = make_module(prepared)
    for decoder, ok in ((decoder_sizes("small"), True), (decoder_sizes("paper"), False)):
        fit = AutoDecoder(kind="ngc", decoder=decoder, n_codes=4, lr=1e-3)
        path = tmp_path / "fit.ckpt"
        torch.save({"hyper_parameters": dict(fit.hparams), "state_dict": fit.state_dict()}, path)
        if ok:
            init_ngc_from_fit(module, path)
            for k, v in fit.decoder.state_dict().items():
                assert torch.equal(module.ngc.state_dict()[k], v)
        else:
            with pytest.raises(DataError, match="differs"):
                init_ngc_from_fit(module, path)
