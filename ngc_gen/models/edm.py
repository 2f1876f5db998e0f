"""EDM (Karras et al. 2022, "Elucidating the Design Space of Diffusion-Based Generative Models")
for latent vectors: preconditioning, training loss and a residual-MLP denoiser.

Follows NVlabs/edm `training/networks.py` (EDMPrecond) and `training/loss.py` (EDMLoss); the
symbols are the paper's (Table 1): sigma_data, c_skip, c_out, c_in, c_noise, P_mean, P_std.
"""
from __future__ import annotations

import math

import torch
from torch import nn


class EDMPrecond(nn.Module):
    """D(x; sigma) = c_skip(sigma) x + c_out(sigma) F(c_in(sigma) x, c_noise(sigma)).

    `model` is the raw network F: (x (B, D), c_noise (B,)) -> (B, D). The coefficients are
    computed in the dtype of x (float64 inside the sampler); F runs in its parameter dtype.
    """

    def __init__(self, model: nn.Module, sigma_data: float = 1.0, sigma_min: float = 0.0,
                 sigma_max: float = float("inf")):
        super().__init__()
        self.model = model
        self.sigma_data = float(sigma_data)
        self.sigma_min, self.sigma_max = float(sigma_min), float(sigma_max)

    def coefficients(self, sigma: torch.Tensor):
        """(c_skip, c_out, c_in, c_noise), each shaped like sigma."""
        sd = self.sigma_data
        c_skip = sd ** 2 / (sigma ** 2 + sd ** 2)             # Table 1, skip scaling
        c_out = sigma * sd / (sigma ** 2 + sd ** 2).sqrt()    # Table 1, output scaling
        c_in = 1 / (sd ** 2 + sigma ** 2).sqrt()              # Table 1, input scaling
        c_noise = sigma.log() / 4                             # Table 1, noise conditioning
        return c_skip, c_out, c_in, c_noise

    def forward(self, x: torch.Tensor, sigma) -> torch.Tensor:
        """x: (B, D), sigma: scalar, (B,) or (B, 1) -> D(x; sigma): (B, D) in x's dtype."""
        sigma = torch.as_tensor(sigma, dtype=x.dtype, device=x.device).reshape(-1, 1)
        sigma = sigma.expand(x.shape[0], 1)                   # explicit broadcast over the batch
        c_skip, c_out, c_in, c_noise = self.coefficients(sigma)
        dtype = next(self.model.parameters()).dtype
        F_x = self.model((c_in * x).to(dtype), c_noise.flatten().to(dtype))
        return c_skip * x + c_out * F_x.to(x.dtype)


class EDMLoss:
    """Training loss of EDM (Sec. 5, Table 1): ln sigma ~ N(P_mean, P_std^2),
    lambda(sigma) = (sigma^2 + sigma_data^2) / (sigma sigma_data)^2,
    loss = lambda(sigma) |D(y + n; sigma) - y|^2 with n ~ N(0, sigma^2 I)."""

    def __init__(self, P_mean: float = -1.2, P_std: float = 1.2, sigma_data: float = 1.0):
        self.P_mean, self.P_std, self.sigma_data = P_mean, P_std, sigma_data

    def __call__(self, net, y: torch.Tensor, generator: torch.Generator | None = None):
        """y: (B, D) clean (standardised) latents -> per-element weighted loss (B, D)."""
        dev = generator.device if generator is not None else y.device
        rnd_normal = torch.randn((y.shape[0], 1), generator=generator, device=dev).to(y)
        sigma = (rnd_normal * self.P_std + self.P_mean).exp()           # ln sigma ~ N(P_mean, P_std^2)
        weight = (sigma ** 2 + self.sigma_data ** 2) / (sigma * self.sigma_data) ** 2  # lambda(sigma)
        n = torch.randn(y.shape, generator=generator, device=dev).to(y) * sigma
        D_yn = net(y + n, sigma)
        return weight * ((D_yn - y) ** 2)


class FourierEmbedding(nn.Module):
    """c_noise (B,) -> sqrt(2) cos(2 pi (f c_noise + phi)): (B, channels), f ~ N(0, scale^2),
    phi ~ U(0, 1) fixed at construction (stored as buffers, so in the checkpoint). As EDM2's
    MPFourier: random frequencies resolve c_noise = ln(sigma)/4, which spans only about [-1.6, 1.1]."""

    def __init__(self, channels: int, scale: float = 1.0):
        super().__init__()
        self.register_buffer("freqs", torch.randn(channels) * scale)
        self.register_buffer("phases", torch.rand(channels))

    def forward(self, c_noise: torch.Tensor) -> torch.Tensor:
        y = torch.outer(c_noise, self.freqs.to(c_noise.dtype)) + self.phases.to(c_noise.dtype)
        return math.sqrt(2) * torch.cos(2 * math.pi * y)


class ResidualBlock(nn.Module):
    """h + W2 SiLU(W1 SiLU(FiLM(LayerNorm(h); emb))): FiLM = (1 + scale) * h + shift from emb."""

    def __init__(self, width: int, emb_dim: int, dropout: float = 0.0):
        super().__init__()
        self.norm = nn.LayerNorm(width)
        self.film = nn.Linear(emb_dim, 2 * width)
        self.fc1 = nn.Linear(width, width)
        self.fc2 = nn.Linear(width, width)
        self.dropout = nn.Dropout(dropout)

    def forward(self, h: torch.Tensor, emb: torch.Tensor) -> torch.Tensor:
        scale, shift = self.film(emb).chunk(2, dim=-1)
        y = self.norm(h) * (1 + scale) + shift
        y = self.fc1(nn.functional.silu(y))
        y = self.fc2(self.dropout(nn.functional.silu(y)))
        return h + y


class ResidualMLPDenoiser(nn.Module):
    """The raw network F for latent vectors: (x (B, dim), c_noise (B,)) -> (B, dim).

    Linear in, `depth` FiLM-conditioned residual blocks of `width`, LayerNorm + SiLU + Linear out
    (zero-initialised, so D(x; sigma) = c_skip x at start: the exact denoiser of N(0, sd^2 I)).
    Noise conditioning: Fourier features of c_noise through a 2-layer SiLU MLP.
    """

    def __init__(self, dim: int, width: int = 512, depth: int = 3, emb_dim: int | None = None,
                 fourier_channels: int = 64, fourier_scale: float = 1.0, dropout: float = 0.0):
        super().__init__()
        emb_dim = emb_dim or width
        self.dim, self.width, self.depth = dim, width, depth
        self.fourier = FourierEmbedding(fourier_channels, fourier_scale)
        self.emb = nn.Sequential(nn.Linear(fourier_channels, emb_dim), nn.SiLU(),
                                 nn.Linear(emb_dim, emb_dim), nn.SiLU())
        self.inp = nn.Linear(dim, width)
        self.blocks = nn.ModuleList(ResidualBlock(width, emb_dim, dropout) for _ in range(depth))
        self.out_norm = nn.LayerNorm(width)
        self.out = nn.Linear(width, dim)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, c_noise: torch.Tensor) -> torch.Tensor:
        emb = self.emb(self.fourier(c_noise.reshape(-1).expand(x.shape[0])))
        h = self.inp(x)
        for block in self.blocks:
            h = block(h, emb)
        return self.out(nn.functional.silu(self.out_norm(h)))
