"""Auto-decoder training (DeepSDF style) for NGC (one code per GC) and DeepSDF (one per shape).

loss = mean |F(z_id, x) - sdf| (optionally both clamped to +-clamp) + code_reg * mean ||z||^2
(paper: 1e-4). With the blended union and `loss_shares` a batch also carries each row's share
of its sample, w_j / sum_k w_k over the GCs k holding the sample (`ngc_gen.geometry.union`), and
the L1 term is their weighted mean: sum_j w_j |f_j - sdf| / sum_j w_j bounds the blend's own
error |sum_j w_j f_j / sum_j w_j - sdf| from above (a GC fading out is not held to samples
where the next GC speaks). Off by default: on the ant it left the blend's junctions worse than
the plain loss (docs/fitting.md "Seams"), which trains every GC on every sample it holds, the
estimates the blend averages. Phase two (paper): from `codes_only_from` x max_steps the
decoder's learning rate is zero and only the codes move (an lr switch rather than
requires_grad, so it is resume- and DDP-safe). An optional `scheduler` (ngc_gen.lit.schedules,
`_partial_: true`)
scales both learning rates per step (DeepSDF: halved at fixed intervals).
"""
from __future__ import annotations

import lightning as L
import torch
from torch import nn

from .fitted import CHECKPOINT_KIND  # noqa: F401  (defined there: loading needs no Lightning)
from .parts import decoder_and_kind, optimizer_factory


UNIONS = ("min", "blend")


def check_union(union) -> dict | None:
    """A `model.union` setting as a plain dict ({kind: min} or {kind: blend, width}), checked."""
    if union is None:
        return None
    union = dict(union)
    kind = union.get("kind")
    if kind not in UNIONS:
        raise ValueError(f"model.union.kind must be one of {UNIONS}, got {kind!r}")
    if kind == "blend":
        from ngc_gen.geometry.union import check_width

        union["width"] = check_width(union.get("width", 0.0))
        union["k"] = float(union.get("k") or 0.0)
        union["loss_shares"] = bool(union.get("loss_shares", False))
        if union["k"] < 0:
            raise ValueError(f"model.union.k must be >= 0 (0: the weighted mean), got "
                             f"{union['k']}")
    return union


class AutoDecoder(L.LightningModule):
    """`decoder`: an NGCDecoder or DeepSDFDecoder (built from conf/model's `_target_`), or its
    sizes with `kind` (a checkpoint's record: hparams keep kind and sizes); `optimizer`: a
    partial optimiser (Adam if None) given [decoder group, codes group]; `scheduler`: a partial
    LR scheduler given (optimizer, total_steps=trainer.max_steps), or None (constant learning
    rates); `pe_anneal` > 0: the NGC decoder's encoding bands open one after the other over that
    fraction of the steps (coarse-to-fine), all open afterwards; `union`: how the GCs' fields
    combine, {kind: min} or {kind: blend, width, k, loss_shares} (recorded: shapes of the fit
    use it; None, as in checkpoints from before it was recorded, is the min). Defaults are those of
    conf/model/small.yaml, the default `model` (tests/app/test_config.py keeps them equal);
    `lr` has none: the presets differ (small 1e-2, paper 1e-4, DeepSDF 1e-3 / 5e-4)."""

    def __init__(self, decoder: nn.Module | dict, n_codes: int, lr: float,
                 kind: str | None = None, code_lr: float = 1e-3, code_reg: float = 1e-4,
                 clamp: float | None = None, codes_only_from: float = 0.8,
                 code_init_std: float = 0.01, pe_anneal: float = 0.0, optimizer=None,
                 scheduler=None, union: dict | None = None,
                 meta: dict | None = None, checkpoint_kind: str = CHECKPOINT_KIND):
        super().__init__()
        self.save_hyperparameters(ignore=["decoder", "optimizer", "scheduler"])
        self.hparams.union = check_union(union)
        self.decoder, kind = decoder_and_kind(decoder, kind)
        self.hparams.update(kind=kind, decoder=dict(self.decoder.config))
        self.make_optimizer = optimizer_factory(optimizer)
        self.make_scheduler = scheduler
        self.codes = nn.Embedding(n_codes, self.decoder.code_dim)
        nn.init.normal_(self.codes.weight, 0.0, code_init_std)

    def sdf(self, ids: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        return self.decoder(self.codes(ids), coords)

    def codes_only(self) -> bool:
        max_steps = self.trainer.max_steps if self._trainer is not None else -1
        return max_steps > 0 and self.global_step >= self.hparams.codes_only_from * max_steps

    def on_train_epoch_start(self) -> None:
        dm = getattr(self.trainer, "datamodule", None)
        if dm is not None and hasattr(dm, "set_epoch"):
            dm.set_epoch(self.current_epoch)

    def on_train_batch_start(self, batch, batch_idx) -> None:
        """Phase two: the decoder's lr is 0 for this step (a scheduler, stepped after each
        optimizer step, sets its own value again; without one the lr is the constant lr)."""
        opt = self.optimizers(use_pl_optimizer=False)
        if self.codes_only():
            opt.param_groups[0]["lr"] = 0.0
        elif self.make_scheduler is None:
            opt.param_groups[0]["lr"] = self.hparams.lr

    def on_train_end(self) -> None:
        self._set_bands(None)

    def _set_bands(self, alpha) -> None:
        pe = getattr(self.decoder, "pe", None)
        if pe is not None:
            pe.alpha = alpha

    def training_step(self, batch, batch_idx):
        ids, coords, target = batch[:3]
        share = batch[3] if len(batch) > 3 else None
        if self.hparams.pe_anneal > 0 and self._trainer is not None:  # coarse-to-fine bands
            done = self.global_step / (self.hparams.pe_anneal * max(1, self.trainer.max_steps))
            self._set_bands(None if done >= 1 else done * len(self.decoder.pe.scales))
        z = self.codes(ids)
        pred = self.decoder(z, coords)
        c = self.hparams.clamp
        if c:
            pred, target = pred.clamp(-c, c), target.clamp(-c, c)
        err = (pred - target).abs()
        l1 = err.mean() if share is None else (share * err).sum() / share.sum().clamp(min=1e-12)
        loss = l1 + self.hparams.code_reg * (z * z).sum(1).mean()
        self.log_dict({"train/l1": l1, "train/loss": loss}, prog_bar=True, on_step=True,
                      on_epoch=False)
        return loss

    @property
    def kind(self) -> str:
        return self.hparams.kind

    def configure_optimizers(self):
        opt = self.make_optimizer([
            {"params": self.decoder.parameters(), "lr": self.hparams.lr},
            {"params": self.codes.parameters(), "lr": self.hparams.code_lr},
        ])
        if self.make_scheduler is None:
            return opt
        sched = self.make_scheduler(opt, total_steps=max(1, self.trainer.max_steps))
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}
