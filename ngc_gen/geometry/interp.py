"""Piecewise-linear interpolation on torch tensors (np.interp semantics, vectorised)."""
import torch


def interp(x: torch.Tensor, xp: torch.Tensor, fp: torch.Tensor) -> torch.Tensor:
    """Interpolate fp (M,) or (M, D) given at increasing xp (M,) at x (N,); clamps outside.

    With (xp, fp) and (fp, xp) both strictly increasing, the two maps are exact inverses up to
    rounding, which is what makes s <-> t round trips exact."""
    x = x.contiguous()
    i = torch.clamp(torch.searchsorted(xp, x, right=True) - 1, 0, len(xp) - 2)
    x0, x1 = xp[i], xp[i + 1]
    w = torch.clamp((x - x0) / (x1 - x0), 0.0, 1.0)
    if fp.ndim == 2:
        w = w[:, None]
    return fp[i] * (1 - w) + fp[i + 1] * w


def interp_uniform(x: torch.Tensor, fp: torch.Tensor) -> torch.Tensor:
    """`interp` for fp (M+1,) or (M+1, D) given on the uniform grid linspace(0, 1, M+1).

    The cell index is floor(x * M): no search, which matters on the per-point hot path."""
    M = fp.shape[0] - 1
    xs = torch.clamp(x, 0.0, 1.0) * M
    i = torch.clamp(xs.long(), max=M - 1)
    w = xs - i
    if fp.ndim == 2:
        w = w[:, None]
    return fp[i] * (1 - w) + fp[i + 1] * w
