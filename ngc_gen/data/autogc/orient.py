"""A mesh's up and front: given (`annotate.up`, `annotate.front`) or detected from its limbs.

Names and templates speak of a body frame: front, left, up (left = up x front, so a +z-up mesh
facing +x has +y on its left). A collection's meshes may lie in any frame (a y-up cow facing
+z), so the frame is either given as signed world axes ('+y', '-z') or vectors, or detected
per mesh from its skeleton parts (curves with volumes, the trunk the largest):
- front-back: the world axis closest to the trunk's chord;
- up: of the other two world axes, the one the limbs point along most (mean of their
  root-to-tip unit directions weighted by squared length, roots the ends nearer the trunk: four
  long legs outweigh many short antler tines or ears, and a neck); up is opposite to them (legs hang down). Ambiguous (|mean| below
  ``MIN_LEAN``, or the two axes within ``MIN_MARGIN`` of each other): up falls back to +z;
- front: the longer of the two horizontal world axes of the surface (a body is longer than
  wide), its sign toward the end whose outermost surface (``END_SHARE`` of the length) sits
  higher (a head is held up, a tail hangs), where the ends differ by ``MIN_HEIGHT`` of the
  height; else the side where the parts that do not point down hold more volume.
Detected axes snap to signed world axes: real collections are axis-aligned, and a name must
not flip with a few degrees of pose.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.data.errors import DataError

AXES = {"x": 0, "y": 1, "z": 2}
DEFAULT_UP = np.array([0.0, 0.0, 1.0])
DEFAULT_FRONT = np.array([1.0, 0.0, 0.0])
MIN_LEAN = 0.15    # limbs must lean this much (mean direction over weight) along up
MIN_MARGIN = 0.1   # ... and this much more than along the other candidate axis
END_SHARE = 0.1    # the outermost share of the body length whose height tells head from tail
MIN_HEIGHT = 0.05  # heights of the two ends must differ by this share of the surface's height


@dataclass(frozen=True)
class Orientation:
    """up, front: (3,) unit vectors, orthogonal; source per axis: 'given', 'detected' or
    'default' (detection was ambiguous)."""

    up: np.ndarray
    front: np.ndarray
    source: tuple[str, str] = ("default", "default")

    @property
    def left(self) -> np.ndarray:
        return np.cross(self.up, self.front)

    @property
    def matrix(self) -> np.ndarray:
        """(3, 3) rows front, left, up: body coordinates = world @ matrix.T."""
        return np.stack([self.front, self.left, self.up])

    def describe(self) -> str:
        return f"up {axis_name(self.up)} ({self.source[0]}), front {axis_name(self.front)} ({self.source[1]})"


def axis_name(v: np.ndarray) -> str:
    """'+y' for a signed world axis, else the rounded vector."""
    v = np.asarray(v, dtype=np.float64)
    a = int(np.argmax(np.abs(v)))
    if np.isclose(abs(v[a]), 1.0, atol=1e-6):
        return f"{'+' if v[a] > 0 else '-'}{'xyz'[a]}"
    return str(np.round(v, 3).tolist())


def parse_axis(spec, field: str) -> np.ndarray | None:
    """'+y' / '-z' / 'y' / [x, y, z] -> unit (3,); 'auto' or None -> None (detect).
    DataError naming `field` otherwise."""
    if spec is None or (isinstance(spec, str) and spec.strip().lower() == "auto"):
        return None
    if isinstance(spec, str):
        s = spec.strip().lower()
        sign = -1.0 if s.startswith("-") else 1.0
        s = s.lstrip("+-")
        if s in AXES:
            v = np.zeros(3)
            v[AXES[s]] = sign
            return v
    else:
        v = np.asarray(list(spec), dtype=np.float64) if not np.isscalar(spec) else np.zeros(0)
        if v.shape == (3,) and np.isfinite(v).all() and np.linalg.norm(v) > 0:
            return v / np.linalg.norm(v)
    raise DataError(f"cannot read {spec!r} as a direction", field=field,
                    fix="give a signed world axis such as +y or -z, a vector [x, y, z], or auto")


def _snap(v: np.ndarray) -> np.ndarray:
    a = int(np.argmax(np.abs(v)))
    out = np.zeros(3)
    out[a] = 1.0 if v[a] > 0 else -1.0
    return out


def _limbs(curves: list[np.ndarray], trunk: int) -> list[tuple[int, np.ndarray, float, np.ndarray]]:
    """(index, unit root-to-tip direction, length, tip) of every curve but the trunk."""
    T = curves[trunk]
    out = []
    for i, c in enumerate(curves):
        if i == trunk or len(c) < 2:
            continue
        d0 = np.linalg.norm(T - c[0], axis=1).min()
        d1 = np.linalg.norm(T - c[-1], axis=1).min()
        root, tip = (c[0], c[-1]) if d0 <= d1 else (c[-1], c[0])
        v = tip - root
        n = float(np.linalg.norm(v))
        if n > 1e-9:
            out.append((i, v / n, n, tip))
    return out


def _front_by_height(points: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """The longer horizontal world axis of `points` (N, 3), signed toward its higher end."""
    ua = int(np.argmax(np.abs(up)))
    hor = [a for a in range(3) if a != ua]
    ext = np.ptp(points[:, hor], axis=0)
    axis = np.zeros(3)
    axis[hor[int(np.argmax(ext))]] = 1.0
    s = points @ axis
    h = points @ up
    lo, hi = s.min(), s.max()
    span = hi - lo
    if not span > 0:
        return None
    top_hi = h[s >= hi - END_SHARE * span].max()
    top_lo = h[s <= lo + END_SHARE * span].max()
    if abs(top_hi - top_lo) < MIN_HEIGHT * max(float(np.ptp(h)), 1e-12):
        return None
    return axis if top_hi > top_lo else -axis


def detect_orientation(curves: list[np.ndarray], volumes, trunk: int | None = None,
                       up=None, front=None, points: np.ndarray | None = None) -> Orientation:
    """The body frame of a mesh from its parts (module docstring).

    curves: per part (P, 3) points along it; volumes (G,): their volumes (trunk: the largest,
    unless `trunk` is given); up, front: given axes (unit (3,) or None to detect); points
    (N, 3): surface samples (the front's axis and sign by height; None: by the parts alone)."""
    vol = np.asarray(volumes, dtype=np.float64)
    if trunk is None:
        trunk = int(np.argmax(vol)) if len(vol) else 0
    src_up = "given" if up is not None else "default"
    src_front = "given" if front is not None else "default"
    limbs = _limbs(curves, trunk) if curves else []
    if up is None:
        fa = None
        if front is not None:
            fa = int(np.argmax(np.abs(front)))
        elif curves and len(curves[trunk]) > 1:
            fa = int(np.argmax(np.abs(curves[trunk][-1] - curves[trunk][0])))
        if fa is not None and limbs:
            w = np.array([n * n for _, _, n, _ in limbs])
            mean = (np.array([d for _, d, _, _ in limbs]) * w[:, None]).sum(0) / w.sum()
            cand = [a for a in range(3) if a != fa]
            lean = np.abs(mean[cand])
            best = int(np.argmax(lean))
            if lean[best] >= MIN_LEAN and lean[best] - lean[1 - best] >= MIN_MARGIN:
                up = np.zeros(3)
                up[cand[best]] = -np.sign(mean[cand[best]])
                src_up = "detected"
    if up is None:
        up = DEFAULT_UP.copy()
        if front is not None and abs(front @ up) > 0.9:
            up = np.array([0.0, 1.0, 0.0]) if abs(front[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    up = up / np.linalg.norm(up)
    if front is None and points is not None and len(points) > 1:
        front = _front_by_height(np.asarray(points, dtype=np.float64), up)
        src_front = "detected" if front is not None else src_front
    if front is None and curves and len(curves[trunk]) > 1:
        chord = curves[trunk][-1] - curves[trunk][0]
        chord = chord - (chord @ up) * up
        if np.linalg.norm(chord) > 1e-9:
            axis = _snap(chord)
            center = curves[trunk].mean(axis=0)
            side = 0.0
            for i, d, _, tip in limbs:
                if d @ up > -0.5:  # not a leg: a head, a neck, a tail
                    side += vol[i] * np.sign((tip - center) @ axis)
            if side != 0.0:
                front = axis * np.sign(side)
                src_front = "detected"
    if front is None or abs(front @ up) > 0.9:
        front = DEFAULT_FRONT.copy() if abs(DEFAULT_FRONT @ up) < 0.9 else np.array([0.0, 1.0, 0.0])
        src_front = "default"
    front = front - (front @ up) * up
    front = front / np.linalg.norm(front)
    return Orientation(up=up, front=front, source=(src_up, src_front))


def gcs_orientation(gcs, points: np.ndarray, up=None, front=None) -> Orientation:
    """The body frame of annotated GCs (their curves and volumes as the parts) over surface
    samples `points` (N, 3); up, front: `annotate.up` / `annotate.front` specs (auto: detect)."""
    n = 17
    line = np.stack([np.linspace(-1, 1, n), np.zeros(n), np.zeros(n)], 1)
    curves = [np.asarray(g.to_world(line)) for g in gcs]
    volumes = [float(np.linalg.norm(np.diff(c, axis=0), axis=1).sum()) *
               float(np.mean([np.prod(k["radii"]) for k in g.to_dict()["keys"]]))
               for c, g in zip(curves, gcs)]
    return detect_orientation(curves, volumes, None, parse_axis(up, "annotate.up"),
                              parse_axis(front, "annotate.front"), points)
