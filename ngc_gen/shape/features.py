"""Per-GC feature overrides: the part-mixing half of a shape (paper Sec. 3.2).

GC j of a shape evaluates h(PE(u, a, b), g_j(t)) with g_j(t) = g(f(t)) of its own code. A
`PartFeatures` on GC j replaces that by (1 - w(t)) g(f_A(t)) + w(t) g(f_B(t)), with f_B the
end-feature lerp of another part's code (from the same network: features of different networks
do not mean the same thing). `weight=None` is "replace" (w = 1: exactly part B's features).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch


@dataclass(frozen=True)
class PartFeatures:
    """code: (code_dim,) of the source part; weight: w(t) (t in [0, 1] along the GC) or None
    for replace; label: where the code came from (messages and metrics)."""

    code: torch.Tensor
    weight: Callable | None = None
    label: str = ""

    def key(self) -> tuple:
        """Hashable identity (code bytes + weight repr) for per-GC value caches."""
        return (self.code.detach().cpu().numpy().tobytes(), repr(self.weight))


def blend_features(fa: torch.Tensor, fb: torch.Tensor, t: torch.Tensor, fn) -> torch.Tensor:
    """(1 - w(t)) fa + w(t) fb: fa, fb (N, D) features at the same points (or (D,), broadcast);
    t (N,) in [0, 1]; fn a weight function (None: w = 1)."""
    if fn is None:
        return fb.expand_as(fa) if fb.shape != fa.shape else fb
    w = fn(t).to(dtype=fa.dtype, device=fa.device).unsqueeze(-1)
    return fa + w * (fb - fa)
