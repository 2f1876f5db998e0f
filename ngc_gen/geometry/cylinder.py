"""Generalized cylinder: a curve, a frame field, key radii/twists and end caps.

Relative coordinates (u, a, b) of a world point q (docs/gcs.md): t* = argmin |q - C(t)|
over normalised arc length, p = C(t*), a = (q - p).y / r_y(t*), b = (q - p).z / r_z(t*), u = 2t* - 1;
past an end, s = distance along the end tangent and u = -1 - s/l0 or 1 + s/l1. Inside iff
max(|u| - 1, 0)^2 + a^2 + b^2 <= 1.

t is the network's parameter: normalised arc length, unless an edit (a local stretch) stored
a monotone `reparam` map from t to arc length, so the features and keys of a t-range spread
over a longer (or shorter) piece of curve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .arclength import ArcLength, arc_lengths
from .arrays import DEFAULT_CHUNK, as_numpy, as_tensor, check_points, chunked, dot
from .curves import Curve, curve_from_dict
from .errors import GeometryError
from .frames import FrameField
from .interp import interp
from .relative import near_cover, relative_coordinates
from .relative_tables import (RelativeTables, coarse_convex, coarse_cover, coarse_indices,
                              coarse_owned, coarse_reach, segment_bulge, span_bounds)

GC_KEYS = {"name", "curve", "up", "keys", "caps", "reparam"}
COVER_SAMPLES = 16   # radius samples per polyline segment when sizing the cover balls
KEY_KEYS = {"t", "radii", "twist"}


@dataclass(frozen=True)
class Polyline:
    """Dense polyline x_k = C(s_k) (K+1, 3) at uniform normalised arc length k / K: the seed
    of the closest-point search."""

    x: torch.Tensor
    s: torch.Tensor


@dataclass(frozen=True)
class Key:
    """A key frame at normalised arc length t: radii (r_y, r_z) and twist in degrees."""

    t: float
    radii: tuple[float, float]
    twist: float = 0.0

    def to_dict(self) -> dict:
        return {"t": float(self.t), "radii": [float(r) for r in self.radii],
                "twist": float(self.twist)}


def _parse_key(d, name: str, i: int) -> Key:
    field = f"keys[{i}]"
    if not isinstance(d, dict):
        raise GeometryError(f"each key must be a mapping {{t, radii, twist}}, got {d!r}",
                            name, field)
    unknown = set(d) - KEY_KEYS
    if unknown:
        raise GeometryError(f"unknown key fields {sorted(unknown)}; allowed {sorted(KEY_KEYS)}",
                            name, field)
    if "radii" not in d:
        raise GeometryError("key has no 'radii' ([r_y, r_z] or one number)", name, field)
    try:
        t = float(d.get("t", 0.0))
        r = d["radii"]
        radii = (float(r), float(r)) if np.isscalar(r) else tuple(float(x) for x in r)
        twist = float(d.get("twist", 0.0))
    except (TypeError, ValueError) as e:
        raise GeometryError(f"key values must be numbers ({e})", name, field) from None
    if len(radii) != 2:
        raise GeometryError(f"radii must be [r_y, r_z], got {list(radii)}", name,
                            field + ".radii")
    if not all(np.isfinite(radii)) or min(radii) <= 0:
        raise GeometryError(f"radii must be positive and finite, got {list(radii)}", name,
                            field + ".radii")
    if not (0.0 <= t <= 1.0):
        raise GeometryError(f"t must lie in [0, 1], got {t}", name, field + ".t")
    if not np.isfinite(twist):
        raise GeometryError(f"twist must be finite, got {twist}", name, field + ".twist")
    return Key(t, radii, twist)


def _parse_reparam(r, name: str):
    """{t: [...], arc: [...]} (both strictly increasing from 0 to 1) -> (t, arc) arrays."""
    if r is None:
        return None
    if isinstance(r, dict):
        if set(r) != {"t", "arc"}:
            raise GeometryError("reparam must be {t: [...], arc: [...]}", name, "reparam")
        r = (r["t"], r["arc"])
    try:
        tn, ta = (np.asarray(x, dtype=np.float64) for x in r)
    except (TypeError, ValueError):
        raise GeometryError("reparam t and arc must be lists of numbers", name, "reparam") from None
    ok = (tn.ndim == 1 and tn.shape == ta.shape and len(tn) >= 2 and np.all(np.isfinite(tn))
          and np.all(np.isfinite(ta)) and np.all(np.diff(tn) > 0) and np.all(np.diff(ta) > 0)
          and tn[0] == 0 == ta[0] and tn[-1] == 1 == ta[-1])
    if not ok:
        raise GeometryError("reparam t and arc must be equally long, strictly increasing, from "
                            "0 to 1", name, "reparam")
    if np.array_equal(tn, ta):
        return None
    return tn, ta


class GeneralizedCylinder:
    """A GC around a smooth curve; all queries are batched and vectorised.

    Points may be numpy arrays or torch tensors of shape (N, 3), float32 or float64; results
    come back in the same type and float dtype. Relative coordinates run in one fused float64
    pass over all CPU cores (`ngc_gen.geometry.relative`); `to_world` works in float64 torch
    in chunks of `chunk` points so memory stays bounded for millions of points.
    """

    def __init__(self, curve: Curve, keys: list[Key], caps=(0.1, 0.1), up=None,
                 name: str = "gc", segments: int = 128, chunk: int = DEFAULT_CHUNK,
                 reparam=None):
        self.name = str(name)
        self.curve = curve
        self.reparam = _parse_reparam(reparam, self.name)
        if not keys:
            raise GeometryError("needs at least one key with radii", self.name, "keys")
        keys = sorted(keys, key=lambda k: k.t)
        ts = [k.t for k in keys]
        if len(set(ts)) != len(ts):
            raise GeometryError(f"two keys share the same t ({ts})", self.name, "keys")
        self.keys = keys
        try:
            caps = tuple(float(c) for c in caps)
        except (TypeError, ValueError):
            raise GeometryError(f"caps must be two numbers [l0, l1], got {caps!r}",
                                self.name, "caps") from None
        if len(caps) != 2 or not all(np.isfinite(caps)) or min(caps) <= 0:
            raise GeometryError(f"caps must be two positive lengths [l0, l1] (use e.g. 1e-3 for "
                                f"a nearly flat end), got {list(caps)}", self.name, "caps")
        self.caps = caps
        try:
            self.arc = ArcLength(curve)
        except GeometryError as e:
            raise GeometryError(str(e).split(": ", 1)[-1], self.name, e.field) from None
        self.frame_field = FrameField(curve, up, gc_name=self.name)
        self.up = self.frame_field.up
        self.segments = segments
        self.chunk = chunk
        self._key_t = torch.tensor(ts, dtype=torch.float64)
        self._key_r = torch.tensor([k.radii for k in keys], dtype=torch.float64)
        self._key_w = torch.tensor([math.radians(k.twist) for k in keys], dtype=torch.float64)
        t = torch.linspace(0.0, 1.0, segments + 1, dtype=torch.float64)
        poly_s = self.arc.s_of_t(t)
        self.polyline = Polyline(curve.evaluate(poly_s)[0], poly_s)
        self._twisted = any(k.twist != 0.0 for k in keys)
        self._tables: RelativeTables | None = None

    # ---- construction / serialisation -------------------------------------------------------
    @classmethod
    def from_dict(cls, d: dict, **kwargs) -> "GeneralizedCylinder":
        """Build from the annotation dict of docs/gcs.md (twist in degrees)."""
        if not isinstance(d, dict):
            raise GeometryError(f"a GC must be a mapping, got {type(d).__name__}")
        name = str(d.get("name", "gc"))
        unknown = set(d) - GC_KEYS
        if unknown:
            raise GeometryError(f"unknown fields {sorted(unknown)}; allowed {sorted(GC_KEYS)}",
                                name)
        for required in ("curve", "keys"):
            if required not in d:
                raise GeometryError(f"missing required field '{required}'", name, required)
        try:
            curve = curve_from_dict(d["curve"])
        except GeometryError as e:
            raise GeometryError(str(e).split(": ", 1)[-1], name, e.field) from None
        keys = d["keys"]
        if not isinstance(keys, list):
            raise GeometryError("keys must be a list of {t, radii, twist}", name, "keys")
        keys = [_parse_key(k, name, i) for i, k in enumerate(keys)]
        return cls(curve, keys, caps=d.get("caps", (0.1, 0.1)), up=d.get("up"), name=name,
                   reparam=d.get("reparam"), **kwargs)

    def to_dict(self) -> dict:
        return {"name": self.name, "curve": self.curve.to_dict(),
                "up": [float(x) for x in self.up],
                "keys": [k.to_dict() for k in self.keys],
                "caps": [float(c) for c in self.caps],
                **({} if self.reparam is None else
                   {"reparam": {"t": self.reparam[0].tolist(), "arc": self.reparam[1].tolist()}})}

    def replace(self, curve: Curve | None = None, keys: list[Key] | None = None, caps=None,
                up=None, name: str | None = None, reparam="keep") -> "GeneralizedCylinder":
        """A new GC with some parts replaced (GCs are immutable values); reparam=None resets
        the parameter map to the identity."""
        reparam = self.reparam if isinstance(reparam, str) and reparam == "keep" else reparam
        return GeneralizedCylinder(curve or self.curve, keys if keys is not None else self.keys,
                                   caps if caps is not None else self.caps,
                                   up if up is not None else self.up, name or self.name,
                                   self.segments, self.chunk, reparam)

    # ---- parameter map: the network's t <-> normalised arc length ---------------------------
    def arc_of_t(self, t: torch.Tensor) -> torch.Tensor:
        """Network parameter t (what u = 2t - 1 and the keys refer to) -> normalised arc length.
        The identity unless an edit (stretch) reparameterised the GC."""
        if self.reparam is None:
            return t
        tn, ta = (torch.as_tensor(x, dtype=t.dtype, device=t.device) for x in self.reparam)
        return interp(t, tn, ta)

    def t_of_arc(self, ta: torch.Tensor) -> torch.Tensor:
        if self.reparam is None:
            return ta
        tn, tar = (torch.as_tensor(x, dtype=ta.dtype, device=ta.device) for x in self.reparam)
        return interp(ta, tar, tn)

    def transformed(self, R, t) -> "GeneralizedCylinder":
        """The GC under the rigid motion x -> R x + t (R a rotation); relative coords invariant."""
        R = np.asarray(R, dtype=np.float64)
        return self.replace(curve=self.curve.transformed(R, t), up=R @ self.up)

    @property
    def length(self) -> float:
        return self.arc.length

    # ---- profiles --------------------------------------------------------------------------
    def radii_at(self, t: torch.Tensor) -> torch.Tensor:
        """(N,) normalised arc length -> (N, 2) radii, lerped between keys, clamped at ends."""
        if len(self.keys) == 1:
            return self._key_r.to(t.device).expand(len(t), 2)
        return interp(t, self._key_t.to(t.device), self._key_r.to(t.device))

    def twist_at(self, t: torch.Tensor) -> torch.Tensor:
        """(N,) -> (N,) twist angle in radians, lerped between keys."""
        if len(self.keys) == 1:
            return self._key_w.to(t.device).expand(len(t))
        return interp(t, self._key_t.to(t.device), self._key_w.to(t.device))

    def frame(self, s: torch.Tensor, t: torch.Tensor):
        """Point, unit tangent, normal, binormal at curve parameter s (t its arc length)."""
        C, d1, _ = self.curve.evaluate(s)
        T = d1 / torch.sqrt(dot(d1, d1))[:, None]
        N, B = self.frame_field.frames(s, T, self.twist_at(t) if self._twisted else None)
        return C, T, N, B

    # ---- relative coordinates --------------------------------------------------------------
    @property
    def tables(self) -> RelativeTables:
        """What the fused relative-coordinate kernel reads (built once per GC)."""
        if self._tables is None:
            breaks, coef = self.curve.pieces()
            x = self.polyline.x.numpy()
            coarse = coarse_indices(len(x), max(2, round(math.sqrt(self.segments))))
            rep = (np.zeros(0), np.zeros(0)) if self.reparam is None else self.reparam
            ps = self.polyline.s
            chord, bulge = segment_bulge(x, arc_lengths(self.curve, ps[:-1], ps[1:]).numpy())
            owned = coarse_owned(coarse)
            ctt = self.curvature_vectors()
            span_k, span_dk = span_bounds(ctt, owned, self.segments, self.length)
            self._tables = RelativeTables(
                breaks=breaks, coef=np.ascontiguousarray(coef), poly_x=np.ascontiguousarray(x),
                poly_s=self.polyline.s.numpy().copy(),
                poly_d=np.ascontiguousarray(self.curve.evaluate(self.polyline.s)[1].numpy()),
                coarse=coarse,
                cover=coarse_cover(x, self.cover_radii(), coarse),
                convex=coarse_convex(np.linalg.norm(ctt, axis=1), coarse, self.segments,
                                     self.length),
                chord=chord, bulge=bulge, owned=owned,
                reach=coarse_reach(x, bulge, coarse, owned), span_k=span_k, span_dk=span_dk,
                arc_t=self.arc.t_table.numpy().copy(), rep_arc=np.ascontiguousarray(rep[1]),
                rep_t=np.ascontiguousarray(rep[0]),
                frame_r=np.ascontiguousarray(self.frame_field.r_table.numpy()),
                key_t=self._key_t.numpy().copy(), key_r=self._key_r.numpy().copy(),
                key_w=self._key_w.numpy().copy(), twisted=self._twisted,
                caps=np.asarray(self.caps, dtype=np.float64), length=float(self.length))
        return self._tables

    def curvature_vectors(self) -> np.ndarray:
        """(K COVER_SAMPLES + 1, 3) C_tt = kappa N (second derivative in arc length) at uniform
        arc length: C'' less its part along C', over |C'|^2."""
        ta = torch.linspace(0.0, 1.0, self.segments * COVER_SAMPLES + 1, dtype=torch.float64)
        _, d1, d2 = self.curve.evaluate(self.arc.s_of_t(ta))
        n2 = dot(d1, d1)[:, None]
        return ((d2 - dot(d2, d1)[:, None] * d1 / n2) / n2).numpy()

    def curvature_samples(self) -> np.ndarray:
        """(K COVER_SAMPLES + 1,) curvature |C' x C''| / |C'|^3 at uniform arc length."""
        return np.linalg.norm(self.curvature_vectors(), axis=1)

    def cover_radii(self) -> np.ndarray:
        """(K+1,) radii of balls around the polyline vertices whose union holds the GC.

        A point inside has its foot point C(t) within max(r_y, r_z)(t) (tube; Newton makes the
        offset perpendicular to the tangent) or within max(l, r_y, r_z) of an end (caps).
        Vertex k sits at arc length t_k = k / K and answers for t within half a segment of
        it: C(t) is within L / 2K of it, and the largest radius over that window is bounded by
        the largest of COVER_SAMPLES samples per segment plus the largest change between
        neighbouring samples (radii are piecewise linear)."""
        K, n = self.segments, COVER_SAMPLES
        ta = torch.linspace(0.0, 1.0, K * n + 1, dtype=torch.float64)
        r = self.radii_at(self.t_of_arc(ta)).max(1).values.numpy()
        slack = np.abs(np.diff(r)).max() if len(r) > 1 else 0.0
        h = n // 2
        padded = np.concatenate([np.full(h, r[0]), r, np.full(h, r[-1])])
        window = np.lib.stride_tricks.sliding_window_view(padded, 2 * h + 1)[::n].max(1)
        out = window + slack + self.length / (2 * K) * (1 + 1e-6)
        out[0] = max(out[0], max(self.caps[0], r[0]))
        out[-1] = max(out[-1], max(self.caps[1], r[-1]))
        return out * (1 + 1e-9) + 1e-12

    def _to_world(self, rel: torch.Tensor) -> torch.Tensor:
        u, a, b = rel.unbind(1)
        t = ((u.clamp(-1.0, 1.0) + 1.0) / 2.0)
        s = self.arc.s_of_t(self.arc_of_t(t))
        s = torch.where(u <= -1.0, torch.zeros_like(s), torch.where(u >= 1.0, torch.ones_like(s), s))
        t = torch.where(u <= -1.0, torch.zeros_like(t), torch.where(u >= 1.0, torch.ones_like(t), t))
        C, T, N, B = self.frame(s, t)
        cap = torch.where(u < -1.0, (u + 1.0) * self.caps[0],
                          torch.where(u > 1.0, (u - 1.0) * self.caps[1], torch.zeros_like(u)))
        r = self.radii_at(t)
        return C + cap[:, None] * T + (a * r[:, 0])[:, None] * N + (b * r[:, 1])[:, None] * B

    def to_relative(self, points):
        """points (N, 3) -> (N, 3) [u, a, b]; u in [-2, 2] for points inside."""
        q, back = as_numpy(points)
        check_points(q)
        return back(relative_coordinates(self.tables, q, dtype=q.dtype, with_measure=False)[0])

    def relative_inside(self, points, cull: bool = True):
        """points (N, 3) -> (rel (N, 3), measure (N,) float64) with measure =
        max(|u|-1, 0)^2 + a^2 + b^2 (inside iff <= 1). With `cull`, points the cover balls rule
        out skip the closest-point solve: rel NaN, measure inf (the others are computed exactly
        as without). rel comes back in the caller's type/dtype, measure as a numpy array."""
        q, back = as_numpy(points)
        check_points(q)
        rel, measure = relative_coordinates(self.tables, q, cull=cull, dtype=q.dtype)
        return back(rel), measure

    def near(self, points, pad: float) -> np.ndarray:
        """points (N, 3) -> (N,) bool, False where the point is farther than `pad` from the GC
        (conservative: True may still be outside)."""
        q, _ = as_numpy(points)
        check_points(q)
        return near_cover(self.tables, q, pad)

    def to_world(self, rel):
        """[u, a, b] (N, 3) -> world points (N, 3); inverse of to_relative inside the GC."""
        x, back = as_tensor(rel)
        check_points(x, "relative coordinates")
        return back(chunked(self._to_world, x, self.chunk))

    def centre_line(self, n: int) -> np.ndarray:
        """(n, 3) float64 world points of the curve at n evenly spaced normalised arc lengths
        from start to end (relative coordinates (u, 0, 0), u in [-1, 1])."""
        u = np.linspace(-1.0, 1.0, n)
        return np.asarray(self.to_world(np.stack([u, np.zeros(n), np.zeros(n)], 1)),
                          dtype=np.float64)

    def mean_radius(self) -> float:
        """The mean over the keys of each key's ellipse radius sqrt(r_y r_z) (its geometric
        mean: the radius of the circle of the same area)."""
        return float(torch.sqrt(self._key_r.prod(dim=1)).mean())

    @staticmethod
    def relative_measure(rel):
        """(N, 3) relative coords -> (N,) rho^2 = max(|u|-1, 0)^2 + a^2 + b^2: 1 on the GC's
        boundary, below inside (rho: the relative radius, in units of the radii and caps)."""
        if isinstance(rel, torch.Tensor):
            e = torch.clamp(rel[:, 0].abs() - 1.0, min=0.0)
        else:
            e = np.clip(np.abs(rel[:, 0]) - 1.0, 0.0, None)
        return e * e + rel[:, 1] ** 2 + rel[:, 2] ** 2

    @staticmethod
    def inside_relative(rel):
        """(N, 3) relative coords -> (N,) bool: inside, `relative_measure` <= 1."""
        return GeneralizedCylinder.relative_measure(rel) <= 1.0

    def contains(self, points):
        """points (N, 3) -> (N,) bool inside the GC (tube plus half-ellipsoid caps)."""
        _, measure = self.relative_inside(points)
        inside = measure <= 1.0
        if isinstance(points, torch.Tensor):
            return torch.from_numpy(inside).to(points.device)
        return inside

    def bounds(self, samples: int = 256) -> tuple[np.ndarray, np.ndarray]:
        """Conservative axis-aligned box (lo, hi) of the GC including caps."""
        if getattr(self, "_bounds", None) is None:
            t = torch.linspace(0.0, 1.0, samples + 1, dtype=torch.float64)
            s = self.arc.s_of_t(self.arc_of_t(t))
            C, T, N, B = self.frame(s, t)
            r = self.radii_at(t)
            # extent of an ellipse with axes r_y N, r_z B along each world axis
            ext = torch.sqrt((r[:, :1] * N) ** 2 + (r[:, 1:] * B) ** 2)
            lo, hi = (C - ext).min(0).values, (C + ext).max(0).values
            for i, l in ((0, self.caps[0]), (-1, self.caps[1])):  # full end ellipsoids
                e = torch.sqrt((l * T[i]) ** 2 + (r[i, 0] * N[i]) ** 2 + (r[i, 1] * B[i]) ** 2)
                lo, hi = torch.minimum(lo, C[i] - e), torch.maximum(hi, C[i] + e)
            step = torch.linalg.norm(C[1:] - C[:-1], dim=1).max()
            pad = step + 0.02 * r.max()
            self._bounds = ((lo - pad).numpy(), (hi + pad).numpy())
        return self._bounds[0].copy(), self._bounds[1].copy()

    def __repr__(self) -> str:
        return (f"GeneralizedCylinder(name={self.name!r}, {self.curve.kind} degree/points="
                f"{len(self.curve.points)}, length={self.length:.4g}, keys={len(self.keys)})")
