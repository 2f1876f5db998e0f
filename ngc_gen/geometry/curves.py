"""Continuously differentiable space curves on their own parameter s in [0, 1].

Two kinds, as docs/gcs.md asks: Bezier curves of any degree (control points are the
editing handles) and C2 cubic splines through polyline points (the reference code's skeleton
format, chord-length parameterised). Both evaluate position and first two derivatives in
closed form, which the Newton closest-point refinement needs.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np
import torch
from scipy.interpolate import CubicSpline

from .errors import GeometryError


def _check_points(points, kind: str, min_points: int) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise GeometryError(f"{kind} points must be a list of [x, y, z], got shape {p.shape}",
                            field="curve.points")
    if len(p) < min_points:
        raise GeometryError(f"a {kind} curve needs at least {min_points} points, got {len(p)}",
                            field="curve.points")
    if not np.all(np.isfinite(p)):
        raise GeometryError(f"{kind} points contain NaN or inf", field="curve.points")
    return p


def bernstein_basis(degree: int, s) -> np.ndarray:
    """(N, degree + 1) Bernstein polynomials B_i(s) = C(n, i) s^i (1 - s)^(n - i) at s (N,): the one
    Bezier basis (control points -> points is `bernstein_basis(n, s) @ points`; least-squares
    fits solve against it)."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    i = np.arange(degree + 1, dtype=np.float64)[None, :]
    binom = np.array([math.comb(degree, k) for k in range(degree + 1)], dtype=np.float64)
    return binom * s ** i * (1.0 - s) ** (degree - i)


class Curve(ABC):
    """Base: `evaluate(s)` returns C(s), C'(s), C''(s) as (N, 3) float64 tensors."""

    kind = "curve"
    points: np.ndarray

    @abstractmethod
    def evaluate(self, s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """s: (N,) float64 in [0, 1] -> (C, C', C'') each (N, 3)."""

    @abstractmethod
    def pieces(self) -> tuple[np.ndarray, np.ndarray]:
        """The curve as polynomial pieces: breaks (P+1,) on s and coef (P, D+1, 3), coef[i, k]
        the coefficient of (s - breaks[i])^k (what the fused relative-coordinate kernel reads)."""

    def to_dict(self) -> dict:
        return {"type": self.kind, "points": self.points.tolist()}

    def with_points(self, points) -> "Curve":
        return type(self)(points)

    def transformed(self, R: np.ndarray, t: np.ndarray) -> "Curve":
        """The curve under the rigid (or affine) map x -> R x + t; exact for both kinds."""
        return self.with_points(self.points @ np.asarray(R).T + np.asarray(t))


class BezierCurve(Curve):
    """Bezier curve of degree len(points)-1 >= 1.

    Evaluated in the power basis: one (N, n+1) x (n+1, 9) matmul gives C, C' and C'' at once
    (the Bernstein form costs several times more per point; degrees here are small, so the
    power basis is well conditioned on [0, 1] in float64)."""

    kind = "bezier"

    def __init__(self, points):
        self.points = _check_points(points, "bezier", 2)
        n = len(self.points) - 1
        self.degree = n
        # power-basis coefficients a_k = C(n,k) sum_i (-1)^(k-i) C(k,i) P_i
        a = np.zeros((n + 1, 3))
        for k in range(n + 1):
            for i in range(k + 1):
                a[k] += math.comb(n, k) * math.comb(k, i) * (-1) ** (k - i) * self.points[i]
        k = np.arange(n + 1, dtype=np.float64)[:, None]
        d1 = np.zeros_like(a)
        d1[:-1] = a[1:] * k[1:]
        d2 = np.zeros_like(a)
        d2[:-2] = a[2:] * (k[2:] * (k[2:] - 1))
        self._a = a
        self._M = torch.as_tensor(np.concatenate([a, d1, d2], 1))  # (n+1, 9)

    def pieces(self):
        return np.array([0.0, 1.0]), self._a[None].copy()

    def evaluate(self, s):
        M = self._M.to(device=s.device, dtype=s.dtype)
        powers = torch.cumprod(torch.cat([torch.ones_like(s)[:, None],
                                          s[:, None].expand(-1, self.degree)], 1), 1)
        out = powers @ M
        return out[:, 0:3], out[:, 3:6], out[:, 6:9]


class SplineCurve(Curve):
    """C2 cubic spline through the points, parameterised by normalised chord length."""

    kind = "spline"

    def __init__(self, points):
        self.points = _check_points(points, "spline", 2)
        chords = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        if np.any(chords <= 1e-12 * max(chords.max(), 1.0)):
            i = int(np.argmin(chords))
            raise GeometryError(f"spline points {i} and {i + 1} coincide; remove the duplicate",
                                field="curve.points")
        x = np.concatenate([[0.0], np.cumsum(chords)])
        x /= x[-1]
        bc = "natural" if len(x) > 2 else "not-a-knot"
        cs = CubicSpline(x, self.points, axis=0, bc_type=bc)
        self._x = torch.as_tensor(x)
        self._c = torch.as_tensor(np.ascontiguousarray(cs.c))  # (4, m-1, 3), highest power first

    def pieces(self):
        return self._x.numpy().copy(), np.ascontiguousarray(self._c.numpy()[::-1].transpose(1, 0, 2))

    def evaluate(self, s):
        x = self._x.to(device=s.device, dtype=s.dtype)
        c = self._c.to(device=s.device, dtype=s.dtype)
        i = torch.clamp(torch.searchsorted(x, s.contiguous(), right=True) - 1, 0, len(x) - 2)
        h = (s - x[i])[:, None]
        c3, c2, c1, c0 = c[0, i], c[1, i], c[2, i], c[3, i]
        C = ((c3 * h + c2) * h + c1) * h + c0
        d1 = (3 * c3 * h + 2 * c2) * h + c1
        d2 = 6 * c3 * h + 2 * c2
        return C, d1, d2


CURVE_TYPES = {"bezier": BezierCurve, "spline": SplineCurve}


def curve_from_dict(d: dict) -> Curve:
    """Build a curve from `{type: bezier|spline, points: [[x,y,z], ...]}`."""
    if not isinstance(d, dict):
        raise GeometryError(f"curve must be a mapping with 'type' and 'points', got {d!r}",
                            field="curve")
    kind = d.get("type", "bezier")
    if kind not in CURVE_TYPES:
        raise GeometryError(f"unknown curve type {kind!r}; use one of {sorted(CURVE_TYPES)}",
                            field="curve.type")
    if "points" not in d:
        raise GeometryError("curve has no 'points'", field="curve.points")
    unknown = set(d) - {"type", "points"}
    if unknown:
        raise GeometryError(f"unknown curve keys {sorted(unknown)}", field="curve")
    return CURVE_TYPES[kind](d["points"])
