"""Positional encoding of relative coordinates (NeRF style, as in the NGC reference code)."""
import math

import torch
from torch import nn


class PositionalEncoding(nn.Module):
    """x (..., D) -> [x, sin(2^k pi x), cos(2^k pi x)]_{k<F}: D * (1 + 2F) dims (39 for D=3, F=6)."""

    def __init__(self, in_dim: int = 3, frequencies: int = 6):
        super().__init__()
        self.in_dim, self.frequencies = in_dim, frequencies
        self.register_buffer("scales", (2.0 ** torch.arange(frequencies)) * math.pi,
                             persistent=False)

    @property
    def out_dim(self) -> int:
        return self.in_dim * (1 + 2 * self.frequencies)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.frequencies == 0:
            return x
        xs = (x[..., None] * self.scales).flatten(-2)
        return torch.cat([x, torch.sin(xs), torch.cos(xs)], -1)
