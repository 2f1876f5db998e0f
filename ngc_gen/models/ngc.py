"""The NGC decoder (paper Sec. 3.2). Its sizes are presets in conf/model/*.yaml (small, and
paper: the reference code's code 256, g 3x256, h 4x256, PE 6), nowhere else.

    f0, f1 = split(Linear(z))                 end features of a GC from its code z
    f(t)   = (1 - t) f0 + t f1,  t = clamp((u + 1) / 2, 0, 1)
    sdf    = h([PE(u, a, b), g(f(t))])

g(f(t)) is the per-point feature that part mixing blends (`features` / `sdf_from_features`).
"""
from __future__ import annotations

import torch
from torch import nn

from .encoding import PositionalEncoding
from .mlp import mlp


class NGCDecoder(nn.Module):
    """Shared network for every GC of every shape; the per-GC code selects the part.
    `config`: the sizes, as a checkpoint records them."""

    kind = "ngc"

    def __init__(self, code_dim: int, feature_dim: int, g_hidden: int, g_layers: int,
                 h_hidden: int, h_layers: int, pe_frequencies: int):
        super().__init__()
        self.config = dict(code_dim=code_dim, feature_dim=feature_dim, g_hidden=g_hidden,
                           g_layers=g_layers, h_hidden=h_hidden, h_layers=h_layers,
                           pe_frequencies=pe_frequencies)
        self.code_dim, self.feature_dim = code_dim, feature_dim
        self.ends = nn.Linear(code_dim, 2 * feature_dim)  # ref code: one Linear to 2 x dim
        self.g = mlp(feature_dim, g_hidden, g_layers - 1, g_hidden, final_activation=True)
        self.pe = PositionalEncoding(3, pe_frequencies)
        self.h = mlp(self.pe.out_dim + g_hidden, h_hidden, h_layers - 1, 1)

    def features(self, codes: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """codes (P, code_dim), u (P,) -> g(f(t)) (P, g_hidden)."""
        f0, f1 = self.ends(codes).chunk(2, dim=-1)
        t = ((u + 1.0) * 0.5).clamp(0.0, 1.0)[:, None]
        return self.g(f0 + t * (f1 - f0))

    def sdf_from_features(self, rel: torch.Tensor, feats: torch.Tensor) -> torch.Tensor:
        """rel (P, 3) [u, a, b], feats (P, g_hidden) -> sdf (P,)."""
        return self.h(torch.cat([self.pe(rel), feats], -1))[:, 0]

    def forward(self, codes: torch.Tensor, rel: torch.Tensor) -> torch.Tensor:
        """codes (P, code_dim) per sample, rel (P, 3) -> sdf (P,)."""
        return self.sdf_from_features(rel, self.features(codes, rel[:, 0]))
