"""Normalised arc-length parameter t of a curve, as a dense monotone table s <-> t."""
from __future__ import annotations

import numpy as np
import torch

from .curves import Curve
from .errors import GeometryError
from .interp import interp, interp_uniform

# 4-point Gauss-Legendre nodes/weights on [0, 1]: per-interval quadrature of |C'(s)|
_GL_X = (np.array([-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                   0.8611363115940526]) + 1) / 2
_GL_W = np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                  0.3478548451374538]) / 2


class ArcLength:
    """Dense table (s_k, t_k), k = 0..M, with t the normalised arc length; `length` is total.

    Both directions interpolate the same table linearly, so t_of_s(s_of_t(t)) == t to rounding.
    """

    def __init__(self, curve: Curve, intervals: int = 2048):
        s = torch.linspace(0.0, 1.0, intervals + 1, dtype=torch.float64)
        h = 1.0 / intervals
        nodes = (s[:-1, None] + h * torch.as_tensor(_GL_X)[None]).reshape(-1)
        speed = torch.linalg.norm(curve.evaluate(nodes)[1], dim=1).reshape(intervals, 4)
        seg = h * (speed * torch.as_tensor(_GL_W)).sum(1)
        cum = torch.cat([torch.zeros(1, dtype=torch.float64), torch.cumsum(seg, 0)])
        self.length = float(cum[-1])
        if not np.isfinite(self.length) or self.length < 1e-9:
            raise GeometryError(f"curve has zero length ({self.length:.3g}); its points must not "
                                "all coincide", field="curve.points")
        if torch.any(seg <= 0):
            raise GeometryError("curve stops (zero speed over an interval); remove repeated "
                                "control points", field="curve.points")
        self.s_table = s
        self.t_table = cum / self.length

    def s_of_t(self, t: torch.Tensor) -> torch.Tensor:
        return interp(t, self.t_table.to(device=t.device, dtype=t.dtype),
                      self.s_table.to(device=t.device, dtype=t.dtype))

    def t_of_s(self, s: torch.Tensor) -> torch.Tensor:
        return interp_uniform(s, self.t_table.to(device=s.device, dtype=s.dtype))


def arc_lengths(curve: Curve, a: torch.Tensor, b: torch.Tensor, sub: int = 8) -> torch.Tensor:
    """(n,) arc length of the curve from parameter a to b (n,) each: 4-point Gauss-Legendre on
    `sub` equal pieces of each interval (|C'| is smooth: ~1e-15 relative for a segment of a
    128-segment polyline)."""
    u = ((torch.arange(sub, dtype=a.dtype)[:, None] + torch.as_tensor(_GL_X, dtype=a.dtype)[None])
         / sub).reshape(-1)
    h = b - a
    nodes = (a[:, None] + h[:, None] * u[None]).reshape(-1)
    speed = torch.linalg.norm(curve.evaluate(nodes)[1], dim=1).reshape(len(h), sub, 4)
    return h / sub * (speed * torch.as_tensor(_GL_W, dtype=a.dtype)).sum((1, 2))
