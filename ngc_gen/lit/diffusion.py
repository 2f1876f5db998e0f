"""EDM latent diffusion over one latent vector per shape (docs/generation.md).

Latents are standardised per dimension with the training set's mean and std (buffers, so they
travel in the checkpoint); the EDM works in that space with sigma_data = 1 (the std of the
standardised latents), the same value in loss and preconditioning. `standardise=pca` goes one step
further: the per-dimension standardised latents are rotated onto their principal axes and only
the axes that hold `pca_variance` of the variance are kept (still in per-dimension units, not
whitened); the EDM works in that smaller space (`space_dim`) and what the dropped axes hold is
decoded at the training mean (`pca_complete=mean`) or taken from the training latent nearest on
the kept axes (`pca_complete=nearest`: the kept axes come from the EDM, the detail they leave
out from the data, as a nearest-neighbour regression of the dropped axes on the kept ones;
the residuals travel in the checkpoint). A few hundred latents of a few hundred entries span
at most N - 1 directions and are strongly correlated (a pose moves every GC of a limb), so most
directions of the per-dimension space carry little or no data; the denoiser then fits the
directions that do.
bench/notes/generation.md has the measurements (what the dropped axes cost, and why whitening
the kept axes made samples worse).

Training data: batches of raw latents (B, dim), or (latents,) tuples as from a TensorDataset.
"""
from __future__ import annotations

import copy

import lightning as L
import torch
from torch.utils.data import TensorDataset

from ngc_gen.models.edm import EDMLoss, EDMPrecond, ResidualMLPDenoiser
from ngc_gen.models.sampler import edm_sampler

from .checkpoint import load_module
from . import kinds
from .diffusion_options import PCA_COMPLETE, STANDARDISE
from .parts import keywords, optimizer_factory

CHECKPOINT_KIND = kinds.DIFFUSION  # the one table: ngc_gen/lit/kinds.py


class LatentDiffusion(L.LightningModule):
    """EDM on latent vectors of size `dim`. `denoiser`: a ResidualMLPDenoiser partial
    (`_partial_: true`: the latent size comes from the data) or its keyword arguments (width,
    depth, emb_dim, fourier_channels, fourier_scale, dropout); `optimizer`: a partial optimiser
    (Adam if None). Defaults are conf/diffusion/default.yaml's (tests/app/test_config.py keeps
    them equal)."""

    # checkpoints written before the optimiser came from the config record Adam's betas; they
    # only mattered for training, so loading such a checkpoint drops them
    RETIRED_HPARAMS = ("betas",)

    def __init__(self, dim: int, denoiser=None, lr: float = 1e-3, P_mean: float = -1.2,
                 P_std: float = 1.2, sigma_data: float = 1.0, ema_halflife_steps: float = 500.0,
                 ema_rampup: float | None = 0.05, ema_decay: float | None = None,
                 standardise: str = "per_dim", std_eps: float = 1e-6,
                 pca_variance: float = 0.95, pca_complete: str = "mean",
                 space_dim: int | None = None, bank_size: int = 0, optimizer=None,
                 meta: dict | None = None, checkpoint_kind: str = CHECKPOINT_KIND):
        super().__init__()
        if standardise not in STANDARDISE:
            raise ValueError(f"unknown standardise {standardise!r}; choose one of {STANDARDISE}")
        if not 0.0 < pca_variance <= 1.0:
            raise ValueError(f"pca_variance must be in (0, 1], got {pca_variance}")
        if pca_complete not in PCA_COMPLETE:
            raise ValueError(f"unknown pca_complete {pca_complete!r}; choose one of "
                             f"{PCA_COMPLETE}")
        space_dim = int(space_dim or dim) if standardise == "pca" else dim
        self.save_hyperparameters(ignore=["denoiser", "optimizer"])
        net_kw = keywords(denoiser, ResidualMLPDenoiser)
        self.hparams.update(denoiser=net_kw)   # space_dim: set by _build
        self.make_optimizer = optimizer_factory(optimizer)
        self.loss_fn = EDMLoss(P_mean, P_std, sigma_data)
        self.register_buffer("latent_mean", torch.zeros(dim))
        self.register_buffer("latent_std", torch.ones(dim))
        self.register_buffer("latent_count", torch.zeros((), dtype=torch.long))  # 0: not fitted
        self._build(space_dim)
        self._ema_step = -1

    def _build(self, space_dim: int) -> None:
        """The denoiser (and its EMA copy) over `space_dim` entries; with standardise=pca also
        the principal axes (dim, space_dim) and, with pca_complete=nearest, the training
        latents' coordinates on them (bank_size, space_dim) and what they leave out
        (bank_size, dim), in per-dimension units."""
        self.hparams.space_dim = int(space_dim)
        self.net = EDMPrecond(ResidualMLPDenoiser(space_dim, **self.hparams.denoiser),
                              self.hparams.sigma_data)
        self.ema = copy.deepcopy(self.net).requires_grad_(False)
        if self.hparams.standardise == "pca":
            self.register_buffer("pca_axes", torch.eye(self.hparams.dim)[:, :space_dim])
            if self.hparams.pca_complete == "nearest":
                n = int(self.hparams.bank_size)
                self.register_buffer("pca_bank", torch.zeros(n, space_dim))
                self.register_buffer("pca_residual", torch.zeros(n, self.hparams.dim))

    @property
    def space_dim(self) -> int:
        """Entries of the space the EDM works in: dim, or the kept principal axes (pca)."""
        return int(self.hparams.space_dim)

    # -- standardisation ------------------------------------------------------------------
    @torch.no_grad()
    def fit_standardisation(self, latents: torch.Tensor) -> None:
        """Set the mean/std buffers from training latents (N, dim), N >= 2; with
        standardise=pca also the principal axes holding `pca_variance` of the variance (at most
        N - 1), which sizes the denoiser: call it before training (the stage does)."""
        z = torch.as_tensor(latents).to(torch.float64).reshape(len(latents), -1)
        if z.shape[1] != self.hparams.dim or len(z) < 2:
            raise ValueError(f"need training latents of shape (N >= 2, {self.hparams.dim}); "
                             f"got {tuple(latents.shape)}")
        mode = self.hparams.standardise
        if mode in ("per_dim", "pca"):
            mean, std = z.mean(0), z.std(0)
        elif mode == "scalar":
            mean, std = z.mean().expand(z.shape[1]), z.std().expand(z.shape[1])
        else:
            mean, std = torch.zeros(z.shape[1]), torch.ones(z.shape[1])
        self.latent_mean.copy_(mean)
        self.latent_std.copy_(std.clamp_min(self.hparams.std_eps))
        self.latent_count.fill_(len(z))
        if mode == "pca":
            u = (z - mean) / self.latent_std.to(z)
            _, s, vt = torch.linalg.svd(u, full_matrices=False)
            var = s ** 2 / (len(z) - 1)                       # variance along each axis
            share = var.cumsum(0) / var.sum().clamp_min(1e-300)
            keep = int((share < self.hparams.pca_variance - 1e-12).sum()) + 1
            keep = max(1, min(keep, len(z) - 1, int((var > 1e-12 * var[0]).sum())))
            complete = self.hparams.pca_complete == "nearest"
            if keep != self.space_dim or (complete and len(z) != self.hparams.bank_size):
                self.hparams.bank_size = len(z) if complete else 0
                self._build(keep)
            self.pca_axes.copy_(vt[:keep].T)
            if complete:
                coords = u @ vt[:keep].T
                self.pca_bank.copy_(coords)
                self.pca_residual.copy_(u - coords @ vt[:keep])

    def standardise(self, latents: torch.Tensor) -> torch.Tensor:
        """(B, dim) original -> (B, space_dim) standardised, in latents' dtype (pca: the
        coordinates on the kept axes; what the other axes hold is dropped)."""
        u = (latents - self.latent_mean.to(latents)) / self.latent_std.to(latents)
        if self.hparams.standardise == "pca":
            return u @ self.pca_axes.to(u)
        return u

    def destandardise(self, x: torch.Tensor) -> torch.Tensor:
        """(B, space_dim) standardised -> (B, dim) original, in x's dtype (pca: the dropped
        axes at the training mean, or with pca_complete=nearest as the training latent nearest
        to x on the kept axes has them)."""
        if self.hparams.standardise == "pca":
            u = x @ self.pca_axes.to(x).T
            if self.hparams.pca_complete == "nearest":
                near = torch.cdist(x.detach(), self.pca_bank.to(x)).argmin(1)
                u = u + self.pca_residual.to(x)[near]
            x = u
        return x * self.latent_std.to(x) + self.latent_mean.to(x)

    def _require_standardisation(self) -> None:
        if int(self.latent_count) == 0:
            raise RuntimeError("LatentDiffusion has no latent statistics: call "
                               "fit_standardisation(train_latents) before training, or train "
                               "from a DataLoader over a TensorDataset of the latents")

    # -- EMA -------------------------------------------------------------------------------
    def ema_beta(self, step: int) -> float:
        """EMA decay after optimizer step `step` (>= 1): `ema_decay` if set, else
        0.5 ** (1 / min(ema_halflife_steps, ema_rampup * step)) (NVlabs/edm's ramp-up)."""
        hp = self.hparams
        if hp.ema_decay is not None:
            return float(hp.ema_decay)
        halflife = hp.ema_halflife_steps
        if hp.ema_rampup is not None:
            halflife = min(halflife, step * hp.ema_rampup)
        return 0.5 ** (1.0 / max(halflife, 1e-8))

    @torch.no_grad()
    def update_ema(self, beta: float) -> None:
        """ema <- beta ema + (1 - beta) net, for parameters; buffers are copied."""
        for p_ema, p in zip(self.ema.parameters(), self.net.parameters()):
            p_ema.lerp_(p.detach(), 1.0 - beta)
        for b_ema, b in zip(self.ema.buffers(), self.net.buffers()):
            b_ema.copy_(b)

    # -- training --------------------------------------------------------------------------
    def on_train_start(self) -> None:
        if int(self.latent_count) == 0:
            ds = getattr(self.trainer.train_dataloader, "dataset", None)
            if self.hparams.standardise == "pca":   # the axes size the net the optimiser holds
                raise RuntimeError("standardise=pca sizes the denoiser from the latents: call "
                                   "fit_standardisation(train_latents) before trainer.fit")
            if isinstance(ds, TensorDataset):
                self.fit_standardisation(ds.tensors[0])
        self._require_standardisation()
        self._ema_step = self.global_step

    def training_step(self, batch, batch_idx):
        y = batch[0] if isinstance(batch, (list, tuple)) else batch
        loss = self.loss_fn(self.net, self.standardise(y)).mean()
        self.log("train/loss", loss, prog_bar=True, on_step=True, on_epoch=False,
                 batch_size=len(y))
        return loss

    def on_train_batch_end(self, outputs, batch, batch_idx) -> None:
        if self.global_step > self._ema_step:  # an optimizer step happened (gradient accumulation)
            self.update_ema(self.ema_beta(self.global_step))
            self._ema_step = self.global_step

    def configure_optimizers(self):
        return self.make_optimizer(self.net.parameters(), lr=self.hparams.lr)

    @torch.no_grad()
    def evaluate_loss(self, latents: torch.Tensor, seed: int = 0, use_ema: bool = False,
                      repeats: int = 1) -> float:
        """Mean EDM loss on latents (N, dim) (original space) with noise drawn from `seed`."""
        g = torch.Generator().manual_seed(seed)
        net = self.ema if use_ema else self.net
        y = self.standardise(latents.to(self.device, torch.float32))
        return float(torch.stack([self.loss_fn(net, y, generator=g).mean()
                                  for _ in range(repeats)]).mean())

    # -- sampling --------------------------------------------------------------------------
    @torch.no_grad()
    def sample(self, n: int, generator: torch.Generator | None = None, seed: int | None = None,
               steps: int = 18, churn: float = 0.0, S_min: float = 0.0,
               S_max: float = float("inf"), S_noise: float = 1.0, sigma_min: float = 0.002,
               sigma_max: float = 80.0, rho: float = 7.0, use_ema: bool = True,
               guide=None) -> torch.Tensor:
        """n latents (n, dim) float32 in the ORIGINAL space, on the module's device.

        Noise comes from `generator` (a CPU generator makes results device-independent), else
        from `seed` (default 0): the same seed gives the same latents. churn > 0 selects the
        stochastic sampler (EDM's S_churn; S_min, S_max, S_noise as in NVlabs/edm); give it more
        steps than 18 (gamma saturates at sqrt(2) - 1 and its discretisation error is larger).
        guide: None, or a function (module, net) -> net' that replaces the denoiser D(x; sigma)
        in the sampler (conditional sampling, ngc_gen.generate.condition)."""
        self._require_standardisation()
        if generator is None:
            generator = torch.Generator().manual_seed(0 if seed is None else int(seed))
        elif seed is not None:
            raise ValueError("pass either generator or seed, not both")

        def randn_like(x):
            return torch.randn(x.shape, generator=generator, dtype=x.dtype,
                               device=generator.device).to(x.device)

        net = self.ema if use_ema else self.net
        was_training = net.training
        net.eval()
        try:
            noise = randn_like(torch.empty(n, self.space_dim, dtype=torch.float64,
                                           device=self.device))
            denoiser = net if guide is None else guide(self, net)
            x = edm_sampler(denoiser, noise, randn_like, num_steps=steps, sigma_min=sigma_min,
                            sigma_max=sigma_max, rho=rho, S_churn=churn, S_min=S_min,
                            S_max=S_max, S_noise=S_noise)
        finally:
            net.train(was_training)
        return self.destandardise(x).to(torch.float32)

    # -- loading ---------------------------------------------------------------------------
    @classmethod
    def from_checkpoint(cls, path, map_location="cpu") -> "LatentDiffusion":
        """A LatentDiffusion from a Lightning checkpoint, loaded with weights_only=True."""
        return load_module(cls, path, CHECKPOINT_KIND, "a diffusion checkpoint",
                           "pass the checkpoints/last.ckpt of a `train.py stage=diffusion` run",
                           map_location)
