"""Auto-decoder training: the scheduler a config names is the one Lightning steps, the codes-only
phase still freezes the decoder under it, and coarse-to-fine bands are all open after training."""
from functools import partial

import lightning as L
import torch
from torch.utils.data import DataLoader, TensorDataset

from ngc_gen.lit.autodecoder import AutoDecoder
from ngc_gen.lit.schedules import StepDecay
from ngc_gen.models import NGCDecoder

SIZES = dict(code_dim=8, feature_dim=8, g_hidden=8, g_layers=2, h_hidden=16, h_layers=2,
             pe_frequencies=2)


class Record(L.Callback):
    def __init__(self):
        self.lrs, self.alphas, self.decoder = [], [], []

    def on_before_optimizer_step(self, trainer, module, optimizer):
        self.lrs.append([g["lr"] for g in optimizer.param_groups])  # what this step uses

    def on_train_batch_end(self, trainer, module, outputs, batch, batch_idx):
        self.alphas.append(module.decoder.pe.alpha)  # the bands this step trained with
        self.decoder.append(torch.cat([p.detach().flatten() for p in module.decoder.parameters()]))


def fit(steps: int, **kwargs) -> tuple[AutoDecoder, Record]:
    g = torch.Generator().manual_seed(0)
    n = 2048
    data = TensorDataset(torch.randint(0, 3, (n,), generator=g), torch.rand(n, 3, generator=g),
                         torch.rand(n, generator=g) - 0.5)
    module = AutoDecoder(NGCDecoder(**SIZES), n_codes=3, **{"lr": 1e-3, **kwargs})
    rec = Record()
    L.Trainer(max_steps=steps, logger=False, enable_checkpointing=False,
              enable_progress_bar=False, enable_model_summary=False, callbacks=[rec]).fit(
        module, DataLoader(data, batch_size=256, shuffle=True))
    return module, rec


def test_step_decay_runs_under_lightning_with_the_codes_only_phase():
    module, rec = fit(20, lr=1e-2, code_lr=2e-2, codes_only_from=0.5,
                      scheduler=partial(StepDecay, interval=0.25, factor=0.5))
    # step s (0-based) uses lr x 0.5^(s // 5); the decoder's is 0 from step 10 (phase two)
    assert rec.lrs[4][1] == 2e-2 and rec.lrs[5][1] == 1e-2 and rec.lrs[19][1] == 2e-2 / 8
    assert rec.lrs[4][0] == 1e-2 and rec.lrs[5][0] == 5e-3 and rec.lrs[9][0] == 5e-3
    assert all(lr[0] == 0.0 for lr in rec.lrs[10:])
    for a, b in zip(rec.decoder[9:], rec.decoder[10:]):  # phase two: steps 10.. leave it alone
        assert torch.equal(a, b)
    assert not torch.equal(rec.decoder[0], rec.decoder[9])


def test_coarse_to_fine_bands_open_during_training_and_stay_open():
    module, rec = fit(20, pe_anneal=0.5)
    assert rec.alphas[0] == 0.0 and 0 < rec.alphas[5] < 2 and rec.alphas[10:] == [None] * 10
    assert module.decoder.pe.alpha is None
    x = torch.rand(4, 3)
    module.decoder.pe.alpha = 0.0  # band weights 0: only the raw coordinates remain
    assert torch.all(module.decoder.pe(x)[:, 3:] == 0)
