"""EDM sampler (Karras et al. 2022, Algorithm 2), as `edm_sampler` in NVlabs/edm `generate.py`:
Heun's 2nd-order method on the probability-flow ODE, optional churn (S_churn > 0) for the
stochastic variant. Runs in float64.
"""
from __future__ import annotations

import math

import torch


def edm_sigma_steps(num_steps: int = 18, sigma_min: float = 0.002, sigma_max: float = 80.0,
                    rho: float = 7.0, device=None) -> torch.Tensor:
    """Noise levels t_0 = sigma_max > ... > t_{N-1} = sigma_min, then t_N = 0: (num_steps + 1,)
    float64 (Eq. 5: t_i = (sigma_max^(1/rho) + i/(N-1) (sigma_min^(1/rho) - sigma_max^(1/rho)))^rho)."""
    i = torch.arange(num_steps, dtype=torch.float64, device=device)
    t_steps = (sigma_max ** (1 / rho)
               + i / (num_steps - 1) * (sigma_min ** (1 / rho) - sigma_max ** (1 / rho))) ** rho
    return torch.cat([t_steps, torch.zeros_like(t_steps[:1])])  # t_N = 0


def edm_sampler(net, latents: torch.Tensor, randn_like=torch.randn_like, num_steps: int = 18,
                sigma_min: float = 0.002, sigma_max: float = 80.0, rho: float = 7.0,
                S_churn: float = 0.0, S_min: float = 0.0, S_max: float = float("inf"),
                S_noise: float = 1.0) -> torch.Tensor:
    """Sample x_0 ~ p_data from unit noise `latents`: (B, ...) -> (B, ...) float64.

    net(x, sigma) -> D(x; sigma) (x float64 (B, ...), sigma a 0-d float64 tensor). The
    deterministic sampler (S_churn = 0) evaluates net 2 N - 1 times (35 for N = 18). `randn_like`
    draws the churn noise (pass one bound to a torch.Generator for reproducibility).
    """
    # Clip the range to what the network supports (attributes of EDMPrecond, if present).
    sigma_min = max(sigma_min, getattr(net, "sigma_min", 0.0))
    sigma_max = min(sigma_max, getattr(net, "sigma_max", float("inf")))
    t_steps = edm_sigma_steps(num_steps, sigma_min, sigma_max, rho, device=latents.device)

    x_next = latents.to(torch.float64) * t_steps[0]
    for i, (t_cur, t_next) in enumerate(zip(t_steps[:-1], t_steps[1:])):  # 0, ..., N-1
        x_cur = x_next

        # Increase noise temporarily (Alg. 2, lines 4-6).
        gamma = min(S_churn / num_steps, math.sqrt(2) - 1) if S_min <= t_cur <= S_max else 0.0
        t_hat = t_cur + gamma * t_cur
        x_hat = x_cur + (t_hat ** 2 - t_cur ** 2).sqrt() * S_noise * randn_like(x_cur)

        # Euler step (Alg. 2, lines 7-8).
        denoised = net(x_hat, t_hat).to(torch.float64)
        d_cur = (x_hat - denoised) / t_hat
        x_next = x_hat + (t_next - t_hat) * d_cur

        # 2nd-order correction unless t_next = 0 (Alg. 2, lines 9-11).
        if i < num_steps - 1:
            denoised = net(x_next, t_next).to(torch.float64)
            d_prime = (x_next - denoised) / t_next
            x_next = x_hat + (t_next - t_hat) * (0.5 * d_cur + 0.5 * d_prime)

    return x_next
