"""DeepSDF baseline decoder (Park et al. 2019): world xyz + per-shape code -> SDF.

Sizes are presets in conf/model: `deepsdf` is DeepSDF's 8 x 512 with the latent+xyz skip into
layer 4 (ReLU, tanh output, no dropout/weight-norm for simplicity); `deepsdf_small` has about
the parameter count of the small NGC decoder so the fitting benchmark compares equal budgets.
"""
from __future__ import annotations

import torch
from torch import nn

class DeepSDFDecoder(nn.Module):
    kind = "deepsdf"

    def __init__(self, code_dim: int, hidden: int, layers: int, skip: int):
        super().__init__()
        self.config = dict(code_dim=code_dim, hidden=hidden, layers=layers, skip=skip)
        self.code_dim, self.skip = code_dim, skip
        in_dim = code_dim + 3
        self.layers = nn.ModuleList()
        d = in_dim
        for i in range(layers):
            out = hidden - in_dim if i + 1 == skip else hidden
            self.layers.append(nn.Linear(d, out))
            d = out + in_dim if i + 1 == skip else out
        self.out = nn.Linear(d, 1)

    def forward(self, codes: torch.Tensor, xyz: torch.Tensor) -> torch.Tensor:
        """codes (P, code_dim), xyz (P, 3) -> sdf (P,)."""
        inp = torch.cat([codes, xyz], -1)
        x = inp
        for i, layer in enumerate(self.layers):
            x = torch.relu(layer(x))
            if i + 1 == self.skip:
                x = torch.cat([x, inp], -1)
        return torch.tanh(self.out(x))[:, 0]
