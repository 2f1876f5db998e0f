"""Latent-space helpers: per-shape seeds, linear and spherical interpolation, paths."""
from __future__ import annotations

import numpy as np
import torch


def latent_seed(seed: int, index: int) -> int:
    """The seed of generated shape `index` under `seed`: independent streams per shape, so shape
    i is the same whatever n is asked for."""
    return int(np.random.SeedSequence([int(seed), int(index), 0x5A4D]).generate_state(1)[0])


def lerp(a: torch.Tensor, b: torch.Tensor, alpha: torch.Tensor) -> torch.Tensor:
    """a, b (D,), alpha (S,) -> (S, D): (1 - alpha) a + alpha b (exact at alpha = 0 and 1)."""
    al = alpha.to(a)[:, None]
    return (1.0 - al) * a + al * b


def slerp(a: torch.Tensor, b: torch.Tensor, alpha: torch.Tensor,
          center: torch.Tensor | None = None) -> torch.Tensor:
    """Spherical interpolation about `center` (default the origin; White 2016):
    c + sin((1-alpha) W)/sin W (a-c) + sin(alpha W)/sin W (b-c), W the angle between a-c and b-c.
    Falls back to lerp when they are (anti)parallel. (S, D); exact at alpha = 0 and 1."""
    c = torch.zeros_like(a) if center is None else center.to(a)
    x, y = a - c, b - c
    nx, ny = x.norm(), y.norm()
    cos = (x @ y) / (nx * ny).clamp_min(1e-30)
    omega = torch.arccos(cos.clamp(-1.0, 1.0))
    if float(torch.sin(omega).abs()) < 1e-6:
        return lerp(a, b, alpha)
    al = alpha.to(a)[:, None]
    out = c + (torch.sin((1.0 - al) * omega) * x + torch.sin(al * omega) * y) / torch.sin(omega)
    out[alpha == 0] = a       # exact endpoints (sin(pi) etc. are not exactly 0 in float)
    out[alpha == 1] = b
    return out


def latent_path(a: torch.Tensor, b: torch.Tensor, steps: int, method: str = "lerp",
                center: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """`steps` latents from a to b (D,): (alphas (S,) float64 from 0 to 1, latents (S, D) in a's
    dtype), by lerp, or slerp about `center`; computed in float64, the ends exactly a and b."""
    if method not in ("lerp", "slerp"):
        raise ValueError(f"unknown interpolation {method!r}; use lerp or slerp")
    alphas = torch.linspace(0.0, 1.0, int(steps), dtype=torch.float64)
    if method == "lerp":
        out = lerp(a.double(), b.double(), alphas)
    else:
        out = slerp(a.double(), b.double(), alphas, None if center is None else center.double())
    out = out.to(a.dtype)
    out[0], out[-1] = a, b
    return alphas, out
