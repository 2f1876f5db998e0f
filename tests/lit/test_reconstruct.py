"""Reconstruction into a trained model: only the new codes move, and they recover a shape the
frozen decoder can represent."""
import lightning as L
import torch
from torch.utils.data import DataLoader, TensorDataset

from ngc_gen.lit.reconstruct import codes_only_autodecoder

from ..edit.conftest import make_module


def test_codes_only_fit_recovers_the_codes_and_freezes_the_decoder():
    fit = make_module(seed=0, shapes=("one",))
    target = make_module(seed=1, shapes=("one",)).codes.weight.detach()  # other codes, same net
    g = torch.Generator().manual_seed(0)
    n = 6000
    ids = torch.randint(0, 3, (n,), generator=g)
    rel = torch.rand(n, 3, generator=g) * 2 - 1
    with torch.no_grad():
        sdf = fit.decoder(target[ids], rel)
    before = {k: v.clone() for k, v in fit.decoder.state_dict().items()}
    module = codes_only_autodecoder(fit, n_codes=3, meta=fit.hparams.meta, code_lr=3e-2)
    err0 = (module.sdf(ids, rel) - sdf).abs().mean().item()
    L.Trainer(max_steps=200, logger=False, enable_checkpointing=False, enable_progress_bar=False,
              enable_model_summary=False).fit(
        module, DataLoader(TensorDataset(ids, rel, sdf), batch_size=512, shuffle=True))
    module.eval()
    with torch.no_grad():
        err = (module.sdf(ids, rel) - sdf).abs().mean().item()
    assert err < 0.2 * err0, (err0, err)
    for k, v in module.decoder.state_dict().items():
        assert torch.equal(v, before[k]), k  # the decoder never moved
    assert module.hparams.lr == 0.0 and module.hparams.kind == fit.hparams.kind
