"""Positional encoding of relative coordinates (NeRF style, as in the NGC reference code)."""
import math

import torch
from torch import nn


class PositionalEncoding(nn.Module):
    """x (..., D) -> [x, sin(2^k pi x_d), cos(2^k pi x_d)]_{d<D, k<F_d}: D + 2 sum(F_d) dims (39 for
    D=3, F=6). `frequencies`: one count for every coordinate, or a count per coordinate (NGC:
    [u, a, b], e.g. fewer bands along the axis than across it).

    `alpha` (coarse-to-fine training, BARF): band k is weighted by (1 - cos(pi clamp(alpha - k,
    0, 1))) / 2, so only bands below alpha are on; None (the default, and after training) = all
    bands at full weight."""

    def __init__(self, in_dim: int = 3, frequencies: int | list[int] = 6):
        super().__init__()
        per = [int(frequencies)] * in_dim if isinstance(frequencies, int) else \
            [int(f) for f in frequencies]
        if len(per) != in_dim or min(per) < 0:
            raise ValueError(f"frequencies must be a count >= 0 or {in_dim} of them, "
                             f"got {frequencies!r}")
        self.in_dim, self.frequencies, self.per_dim = in_dim, frequencies, per
        n = max(per)
        self.register_buffer("scales", (2.0 ** torch.arange(n)) * math.pi, persistent=False)
        keep = torch.tensor([k < f for f in per for k in range(n)], dtype=torch.bool)
        self.register_buffer("keep", torch.nonzero(keep)[:, 0], persistent=False)
        self.select = not bool(keep.all())
        self.alpha: float | None = None

    @property
    def out_dim(self) -> int:
        return self.in_dim + 2 * sum(self.per_dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if sum(self.per_dim) == 0:
            return x
        xs = (x[..., None] * self.scales).flatten(-2)
        if self.select:
            xs = xs[..., self.keep]
        s, c = torch.sin(xs), torch.cos(xs)
        if self.alpha is not None:
            k = torch.arange(len(self.scales), dtype=x.dtype, device=x.device)
            w = 0.5 * (1 - torch.cos(math.pi * (self.alpha - k).clamp(0, 1)))
            w = w.repeat(self.in_dim)
            w = w[self.keep] if self.select else w
            s, c = s * w, c * w
        return torch.cat([x, s, c], -1)
