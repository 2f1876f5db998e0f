"""Plain MLPs with SiLU and Kaiming init (the NGC reference code's choices)."""
from torch import nn


def mlp(in_dim: int, hidden: int, layers: int, out_dim: int | None = None,
        activation=nn.SiLU, final_activation: bool = False) -> nn.Sequential:
    """`layers` hidden Linear+activation blocks of width `hidden`, then an optional output
    Linear to `out_dim`. Kaiming-normal weights, zero biases."""
    mods, d = [], in_dim
    for _ in range(layers):
        mods += [nn.Linear(d, hidden), activation()]
        d = hidden
    if out_dim is not None:
        mods.append(nn.Linear(d, out_dim))
        if final_activation:
            mods.append(activation())
    net = nn.Sequential(*mods)
    for m in net:
        if isinstance(m, nn.Linear):
            nn.init.kaiming_normal_(m.weight, nonlinearity="relu")
            nn.init.zeros_(m.bias)
    return net
