"""The joint refinement of every matched GC's curve and radii in torch (docs/transfer.md, step 4)."""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.geometry import bernstein_basis

W_SYMMETRY = 0.01  # refinement: weight of a symmetric pair's mirror mismatch in position (a
                   # posed animal's legs are not mirrored: at 1 a walking horse's front feet
                   # were pulled to their mirrored mean, 0.25 of the leg's length off each)
W_SYMMETRIC_RADII = 1.0  # and in thickness (log radii per key), which posing keeps


def refine(ctrls: list[np.ndarray], own: list[np.ndarray], radius0: list[np.ndarray],
           parents: list[int], partners: list[int], mirror: tuple[np.ndarray, np.ndarray],
           steps: int, seed: int = 0, max_own: int = 1500) -> list[np.ndarray]:
    """Control points (k_g, 3) of every GC optimised together (module docstring, step 5).

    own: each GC's surface samples (M_g, 3); radius0 (K_g,): initial mean radius per key (the
    keys evenly spaced in t); parents: the parent's index (-1: none); partners: the symmetric
    partner's index (-1); mirror: (point, unit normal) of the mid-plane."""
    if steps == 0 or not ctrls:
        return ctrls
    rng = np.random.default_rng(seed)
    dense = 32
    s = np.linspace(0.0, 1.0, dense)
    B = [torch.as_tensor(bernstein_basis(len(c) - 1, s)) for c in ctrls]
    X = [torch.tensor(c, dtype=torch.float64, requires_grad=True) for c in ctrls]
    X0 = [torch.tensor(c, dtype=torch.float64) for c in ctrls]
    logr = [torch.tensor(np.log(np.maximum(r, 1e-4)), dtype=torch.float64, requires_grad=True)
            for r in radius0]
    Q = [torch.as_tensor(o[rng.choice(len(o), min(len(o), max_own), replace=False)]
                         if len(o) else np.zeros((0, 3))) for o in own]
    scale = float(np.mean([np.exp(np.log(np.maximum(r, 1e-4))).mean() for r in radius0]))
    point, normal = (torch.as_tensor(v, dtype=torch.float64) for v in mirror)
    opt = torch.optim.Adam(X + logr, lr=0.2 * scale)
    for _ in range(steps):
        opt.zero_grad()
        curves = [b @ x for b, x in zip(B, X)]
        loss = torch.zeros((), dtype=torch.float64)
        for g, (C, q) in enumerate(zip(curves, Q)):
            if len(q) < 10:
                continue
            d2 = torch.cdist(q, C)
            t_idx = d2.argmin(1)
            inner = (t_idx > 0) & (t_idx < dense - 1)  # past an end: the cap's samples
            if inner.sum() < 5:
                continue
            d = d2[inner, t_idx[inner]]
            keys = torch.linspace(0, 1, len(logr[g]), dtype=torch.float64)
            t = torch.as_tensor(s, dtype=torch.float64)[t_idx[inner]]
            r = torch.exp(_lerp(keys, logr[g], t))
            loss = loss + ((d - r) ** 2).mean() / scale ** 2 + (torch.relu(d - r) ** 2).mean() / scale ** 2
        for g, p in enumerate(parents):
            if p >= 0:
                dmin = torch.linalg.norm(curves[p] - X[g][0], dim=1).min()
                loss = loss + torch.relu(dmin - 0.5 * torch.exp(logr[p]).mean()) ** 2 / scale ** 2
            if partners[g] > g:
                x = X[g]
                mirrored = x - 2.0 * ((x - point) @ normal)[:, None] * normal[None, :]
                mismatch = ((mirrored - X[partners[g]]) ** 2).sum(1).mean() / scale ** 2
                loss = loss + W_SYMMETRY * mismatch
                if len(logr[g]) == len(logr[partners[g]]):  # the same thickness profile
                    loss = loss + W_SYMMETRIC_RADII * ((logr[g] - logr[partners[g]]) ** 2).mean()
        for x, x0 in zip(X, X0):
            if len(x) > 2:
                loss = loss + 0.1 * ((x[2:] - 2 * x[1:-1] + x[:-2]) ** 2).sum() / scale ** 2
            loss = loss + 0.01 * ((x - x0) ** 2).sum() / scale ** 2
        loss.backward()
        opt.step()
    return [x.detach().numpy() for x in X]


def _lerp(keys: torch.Tensor, values: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear values (K,) at keys (K,) evaluated at t (M,)."""
    if len(keys) == 1:
        return values.expand(len(t))
    i = torch.clamp(torch.searchsorted(keys, t, right=True) - 1, 0, len(keys) - 2)
    w = (t - keys[i]) / (keys[i + 1] - keys[i])
    return values[i] * (1 - w) + values[i + 1] * w
