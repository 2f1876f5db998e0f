"""The NGC decoder (paper Sec. 3.2). Its sizes are presets in conf/model/*.yaml (small, and
paper: the reference code's code 256, g 3x256, h 4x256, PE 6), nowhere else.

    f0, f1 = split(Linear(z))                 end features of a GC from its code z
    f(t)   = (1 - t) f0 + t f1,  t = clamp((u + 1) / 2, 0, 1)
    sdf    = h([PE(u, a, b), g(f(t))])

g(f(t)) is the per-point feature that part mixing blends (`features` / `sdf_from_features`).
`sdf_rows` evaluates many GCs in one call (extraction): a code per GC, a GC index per row.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .encoding import PositionalEncoding
from .mlp import mlp


#: rows per block of `NGCDecoder.sdf_rows` without a gradient: an activation of a block (1 MB)
#: stays in cache (measured ~1.1x the rows per second of 4096-row blocks on one thread, same
#: values; within noise inside an extraction)
ROWS_BLOCK = 2048
#: blocks are zero-padded to a multiple of this many rows: BLAS and the vectorised elementwise
#: kernels treat a ragged tail (and tiny matrices) with other code, whose rounding differs, so
#: without it a row's value would depend on where it fell in its call
ROWS_ALIGN = 16


class NGCDecoder(nn.Module):
    """Shared network for every GC of every shape; the per-GC code selects the part.
    `config`: the sizes, as a checkpoint records them."""

    kind = "ngc"

    def __init__(self, code_dim: int, feature_dim: int, g_hidden: int, g_layers: int,
                 h_hidden: int, h_layers: int, pe_frequencies: int | list[int]):
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

    def sdf_rows(self, codes: torch.Tensor, gc_index: torch.Tensor,
                 rel: torch.Tensor) -> torch.Tensor:
        """codes (K, code_dim) one per GC, gc_index (M,) int64 in [0, K), rel (M, 3) -> sdf (M,):
        `forward(codes[gc_index], rel)` up to float rounding, without a code per row.

        The end features and g's first (linear) layer are computed once per GC: W f(t) + b =
        (W f0 + b) + t (W f1 - W f0), so a row only gathers two vectors and lerps them. Without
        a gradient the rows go through in blocks of ROWS_BLOCK, whose activations stay in the
        CPU's cache (measured ~1.4x the throughput of one 65k-row pass), each padded to a
        multiple of ROWS_ALIGN rows, so a row's value does not depend on which rows share its
        call (sparse and reference extraction, incremental and full, give equal values)."""
        f0, f1 = self.ends(codes).chunk(2, dim=-1)
        first = self.g[0]
        a0 = first(f0)
        da = first(f1) - a0
        if torch.is_grad_enabled():
            return self._rows(a0, da, gc_index, rel)
        out = torch.empty(len(rel), dtype=rel.dtype, device=rel.device)
        for s in range(0, len(rel), ROWS_BLOCK):
            g, r = gc_index[s:s + ROWS_BLOCK], rel[s:s + ROWS_BLOCK]
            pad = -len(r) % ROWS_ALIGN
            if pad:
                g = torch.cat([g, g.new_zeros(pad)])
                r = torch.cat([r, r.new_zeros(pad, 3)])
            out[s:s + ROWS_BLOCK] = self._rows(a0, da, g, r)[:len(r) - pad]
        return out

    def _rows(self, a0: torch.Tensor, da: torch.Tensor, gc_index: torch.Tensor,
              rel: torch.Tensor) -> torch.Tensor:
        t = ((rel[:, 0] + 1.0) * 0.5).clamp(0.0, 1.0)[:, None]
        pre = torch.addcmul(a0[gc_index], t, da[gc_index])
        feats = _run(self.g[1:], pre)
        return _run(self.h, torch.cat([self.pe(rel), feats], -1))[:, 0]


def _run(layers: nn.Sequential, x: torch.Tensor) -> torch.Tensor:
    """`layers(x)`, with SiLU in place when no gradient is recorded: a fresh activation tensor
    per layer costs more (allocation, first touch of its pages) than the activation itself."""
    if torch.is_grad_enabled():
        return layers(x)
    for layer in layers:
        x = F.silu(x, inplace=True) if isinstance(layer, nn.SiLU) else layer(x)
    return x
