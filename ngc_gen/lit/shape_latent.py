"""Shape-latent auto-decoder (docs/generation.md; paper Sec. 4.4): one latent s per shape, a
shape decoder s -> (template GC parameters, one NGC code per GC) and a shared NGC decoder.

    loss = mean |F(code_k(s_i), rel) - sdf|                       NGC SDF L1 (rel from the
                                                                  annotated GCs, cached)
         + param_weight * mean_i,p ((theta_hat_ip - theta_ip) / std_p)^2   GC parameters
         + latent_reg * mean_i ||s_i||^2                          (paper: 1e-4)

Optional latent noise (`latent_noise` = rho > 0): in training the decoder sees
s_i + rho * std(s) * eps, std(s) the per-dimension spread of all latents (detached), so it
decodes a neighbourhood of each latent, not just the point: the latent space between and
around the training shapes decodes to clean shapes, which is where a diffusion model's samples
land.

Batches are the fit stage's NGC rows (global GC id, rel (3,), sdf): every shape has the
template's K GCs, so id = shape * K + gc. Only the shapes present in a batch are decoded.
The annotated parameter vectors (`target_params`) and the decoder's parameter statistics are
buffers, so the checkpoint alone rebuilds everything.

Explicit latents (`shape_decoder.explicit`, the default): a latent is [GC parameters in std
units (P), free entries (latent_dim)]. The GC entries are the shape's annotated parameters,
written by `set_targets` and never trained (their gradient is zeroed), so the parameter loss is
0 and latent_reg applies to the free entries; latent noise reaches both, so the codes are
learned as a smooth function of the GCs, which is what conditional sampling asks of them.
"""
from __future__ import annotations

import math

import lightning as L
import torch
from torch import nn

from ngc_gen.models.shape_decoder import GCTemplate, ShapeDecoder

from . import kinds
from .checkpoint import load_module, resolve_checkpoint
from .parts import decoder_and_kind, keywords, optimizer_factory

CHECKPOINT_KIND = kinds.SHAPE_LATENT  # the one table: ngc_gen/lit/kinds.py
FIX = "pass the run directory (or checkpoints/last.ckpt) of a `train.py stage=shape_latent` run"


class ShapeLatentModule(L.LightningModule):
    """n_shapes latents of `latent_dim`; `template`: GCTemplate.to_dict(); `ngc`: the NGC
    decoder (built from the `model` group's decoder) or its sizes (a checkpoint's record);
    `shape_decoder`: a ShapeDecoder partial (`_partial_: true`) or its keyword arguments (hidden,
    layers, bound); `optimizer`: a partial optimiser (Adam if None). meta: {"shapes": [{name,
    annotation_yaml}, ...]} in latent order. Defaults are conf/shape_latent/default.yaml's
    (tests/app/test_config.py keeps them equal)."""

    def __init__(self, n_shapes: int, template: dict, ngc: nn.Module | dict,
                 latent_dim: int = 128, shape_decoder=None, lr: float = 1e-3,
                 latent_lr: float = 1e-3, param_weight: float = 1.0, latent_reg: float = 1e-4,
                 latent_init_std: float = 0.01, latent_noise: float = 0.25,
                 clamp: float | None = None, lr_min_factor: float = 0.1, optimizer=None,
                 meta: dict | None = None, checkpoint_kind: str = CHECKPOINT_KIND):
        super().__init__()
        self.save_hyperparameters(ignore=["ngc", "shape_decoder", "optimizer"])
        self.template = GCTemplate.from_dict(template)
        self.ngc, kind = decoder_and_kind(ngc, None if isinstance(ngc, nn.Module) else "ngc")
        if kind != "ngc":
            raise ValueError(f"the shape-latent model needs an NGC decoder, got a {kind} one")
        sd = keywords(shape_decoder, ShapeDecoder)
        if isinstance(shape_decoder, dict) and "explicit" not in sd:
            sd["explicit"] = False  # a checkpoint's record from before explicit latents
        self.make_optimizer = optimizer_factory(optimizer)
        self.shape_decoder = ShapeDecoder(latent_dim, self.template.size, self.template.n_gcs,
                                          self.ngc.code_dim, **sd)
        self.hparams.update(ngc=dict(self.ngc.config),  # the layout is always recorded
                            shape_decoder={**sd, "explicit": self.shape_decoder.explicit})
        self.latents = nn.Embedding(n_shapes, self.shape_decoder.in_dim)
        nn.init.normal_(self.latents.weight, 0.0, latent_init_std)
        if self.n_fixed:  # the GC entries stay the annotated parameters
            with torch.no_grad():
                self.latents.weight[:, :self.n_fixed] = 0.0
            keep = torch.ones(self.shape_decoder.in_dim)
            keep[:self.n_fixed] = 0.0
            self.latents.weight.register_hook(lambda g: g * keep.to(g))
        self.register_buffer("target_params", torch.zeros(n_shapes, self.template.size,
                                                          dtype=torch.float64))

    @property
    def n_fixed(self) -> int:
        """Leading latent entries that are GC parameters (explicit latents), else 0."""
        sd = self.shape_decoder
        return sd.n_params if sd.explicit else 0

    @property
    def names(self) -> list[str]:
        return [s["name"] for s in (self.hparams.meta or {}).get("shapes", [])]

    @torch.no_grad()
    def set_targets(self, vectors) -> None:
        """Annotated parameter vectors (n_shapes, P) of the training shapes; also sets the
        shape decoder's parameter statistics from them."""
        v = torch.as_tensor(vectors, dtype=torch.float64)
        if tuple(v.shape) != tuple(self.target_params.shape):
            raise ValueError(f"targets must be {tuple(self.target_params.shape)}, got "
                             f"{tuple(v.shape)}")
        self.target_params.copy_(v)
        self.shape_decoder.set_param_stats(v)
        self.write_gc_entries()

    @torch.no_grad()
    def write_gc_entries(self) -> None:
        """Explicit latents: set each latent's GC entries to its shape's target parameters in
        the decoder's std units (again after the decoder's statistics are replaced)."""
        if self.n_fixed:
            sd = self.shape_decoder
            z = sd.gc_part(sd.normalise(self.target_params.to(sd.param_mean)))
            self.latents.weight[:, :self.n_fixed] = z.to(self.latents.weight)

    # -- decoding ----------------------------------------------------------------------------
    def decode(self, s: torch.Tensor):
        """Latents (B, D) -> (raw GC parameters (B, P) float64, codes (B, K, C))."""
        z, codes = self.shape_decoder(s.to(self.latents.weight))
        return self.shape_decoder.params(z.double()), codes

    def gc_dicts(self, s: torch.Tensor) -> list[list[dict]]:
        """Latents (B, D) -> per shape the list of decoded GC dicts (template order)."""
        theta, _ = self.decode(s)
        return [self.template.gc_dicts(t) for t in theta]

    # -- training ----------------------------------------------------------------------------
    def losses(self, ids: torch.Tensor, rel: torch.Tensor, sdf: torch.Tensor) -> dict:
        K = self.template.n_gcs
        shape, gc = ids // K, ids % K
        uniq, inv = torch.unique(shape, return_inverse=True)
        s = self.latents(uniq)
        s_in = s
        if self.training and self.hparams.latent_noise > 0 and len(self.latents.weight) > 1:
            spread = self.latents.weight.detach().std(0)
            s_in = s + self.hparams.latent_noise * spread * torch.randn_like(s)
        z, codes = self.shape_decoder(s_in)
        pred = self.ngc(codes[inv, gc], rel)
        c = self.hparams.clamp
        if c:
            pred, sdf = pred.clamp(-c, c), sdf.clamp(-c, c)
        l1 = (pred - sdf).abs().mean()
        sd = self.shape_decoder
        varying = sd.varying
        if self.n_fixed or not bool(varying.any()):  # explicit: z is the target by construction
            param = z.sum() * 0
        else:
            target = sd.normalise(self.target_params[uniq]).to(z)
            param = ((z - target)[:, varying] ** 2).mean()
        free = s[:, self.n_fixed:]
        reg = (free * free).sum(1).mean()
        loss = l1 + self.hparams.param_weight * param + self.hparams.latent_reg * reg
        return {"loss": loss, "l1": l1, "param": param, "latent_norm2": reg}

    def on_train_epoch_start(self) -> None:
        dm = getattr(self.trainer, "datamodule", None)
        if dm is not None and hasattr(dm, "set_epoch"):
            dm.set_epoch(self.current_epoch)

    def training_step(self, batch, batch_idx):
        ids, rel, sdf = batch
        out = self.losses(ids, rel, sdf)
        self.log_dict({f"train/{k}": v for k, v in out.items()}, prog_bar=True, on_step=True,
                      on_epoch=False, batch_size=len(ids))
        return out["loss"]

    def configure_optimizers(self):
        hp = self.hparams
        opt = self.make_optimizer([
            {"params": list(self.ngc.parameters()) + list(self.shape_decoder.parameters()),
             "lr": hp.lr},
            {"params": self.latents.parameters(), "lr": hp.latent_lr},
        ])
        max_steps = self.trainer.max_steps if self._trainer is not None else -1
        if max_steps is None or max_steps <= 0 or hp.lr_min_factor >= 1.0:
            return opt
        lo = float(hp.lr_min_factor)

        def factor(step: int) -> float:  # cosine from 1 down to lr_min_factor over max_steps
            x = min(step / max_steps, 1.0)
            return lo + (1.0 - lo) * 0.5 * (1.0 + math.cos(math.pi * x))

        sched = torch.optim.lr_scheduler.LambdaLR(opt, factor)
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "step"}}

    # -- loading -----------------------------------------------------------------------------
    @classmethod
    def from_checkpoint(cls, path, map_location="cpu") -> "ShapeLatentModule":
        """A trained module from a Lightning checkpoint (weights_only), or the checkpoint of a
        run directory (`<run>/checkpoints/last.ckpt`)."""
        path = resolve_checkpoint(path, FIX, "shape-latent run")
        return load_module(cls, path, CHECKPOINT_KIND, "a shape-latent checkpoint", FIX,
                           map_location)
