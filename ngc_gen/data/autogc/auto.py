"""Automatic GCs for a mesh that has no annotation: the two methods and their settings.

- ``skeleton`` (the default, docs/autogc.md): one GC per limb or part from a curve
  skeleton (``skeleton_gcs``).
- ``axis``: one straight GC along the mesh's principal axis (PCA of the vertices) with an
  elliptic profile along the 2nd/3rd principal axes, and end caps sized so every vertex lies
  inside with a small margin (``auto_gc``). The result is checked with ``contains`` and grown
  if needed.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ngc_gen.conf.defaults import yaml_settings
from ngc_gen.data.annotations import Annotation
from ngc_gen.data.errors import DataError
from ngc_gen.data.group_settings import from_group
from ngc_gen.data.mesh.io import is_resource, load_mesh, normalize
from ngc_gen.data.autogc.radii import ellipse_radii, principal_axes
from ngc_gen.data.autogc.orient import parse_axis
from ngc_gen.data.autogc.skeleton_gcs import skeleton_gcs
from ngc_gen.geometry import GeneralizedCylinder

log = logging.getLogger(__name__)


def _cap(s: np.ndarray, slack: np.ndarray, ends: np.ndarray, floor: float) -> tuple[float, float]:
    """Best end position along the axis and its cap length for points past it.

    s: (V,) axial coordinate (the end faces +s); slack: (V,) sqrt(1 - a^2 - b^2) > 0.
    For an end at e, a point with s > e is inside the half-ellipsoid cap of length l iff
    ((s - e)/l)^2 + a^2 + b^2 <= 1, i.e. l >= (s - e)/slack. Picks the e in ``ends`` that
    minimises this end's share of the GC volume, proportional to e + 2/3 l (tube + half
    ellipsoid); a flat end (tiny cap) is allowed but a rounded one wins when it is smaller."""
    best = (np.inf, float(ends[-1]), floor)
    for e in ends:
        past = s > e
        cap = max(float(((s[past] - e) / slack[past]).max()) if past.any() else 0.0, floor)
        if e + 2.0 * cap / 3.0 < best[0]:
            best = (e + 2.0 * cap / 3.0, float(e), cap)
    return best[1], best[2]


def auto_gc(mesh: trimesh.Trimesh | np.ndarray, name: str = "body", margin: float = 0.02,
            max_grow: int = 30) -> GeneralizedCylinder:
    """One straight GC enclosing every vertex of ``mesh`` (a Trimesh or vertices (V, 3)).

    Axis: the first principal axis through the centre of the cross-section's bounding box;
    up = 2nd principal axis, so radii [r_y, r_z] lie along the 2nd and 3rd axes. Radii and caps
    are scaled by (1 + margin). The GC is convex, so holding every vertex means holding every
    surface point. Raises DataError if ``contains`` still misses vertices after ``max_grow``
    growth steps of 5% (not expected; it guards numerical corner cases).
    """
    X = np.asarray(mesh.vertices if isinstance(mesh, trimesh.Trimesh) else mesh, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != 3 or len(X) < 2 or not np.isfinite(X).all():
        raise DataError(f"auto_gc needs finite vertices (V >= 2, 3), got shape {X.shape}", gc=name,
                        fix="load the mesh with load_mesh, which validates it")
    center, axes = principal_axes(X)
    S = (X - center) @ axes.T  # (V, 3) coordinates in the principal frame
    lo, hi = S.min(axis=0), S.max(axis=0)
    size = float((hi - lo).max())
    if not size > 0:
        raise DataError("all vertices coincide", gc=name, fix="give a mesh with extent")
    mid = (lo + hi) / 2.0
    origin = center + mid[1] * axes[1] + mid[2] * axes[2]  # axis through the cross-section box centre
    y, z = S[:, 1] - mid[1], S[:, 2] - mid[2]
    floor = 1e-3 * size  # keeps radii/caps positive for flat or line-like meshes
    ry, rz = (r * (1.0 + margin) for r in ellipse_radii(y, z, floor))
    slack = np.sqrt(np.clip(1.0 - (y / ry) ** 2 - (z / rz) ** 2, 1e-12, None))
    half = (hi[0] - lo[0]) / 2.0
    # Tube ends no closer than 60% of the half extent: a GC that is mostly cap squeezes the
    # middle of the shape into a short u range (a steep, badly learned transition: a torus
    # fitted inside a min-volume auto GC closed its hole). Among those, minimum volume.
    steps = np.linspace(0.6, 1.0, 41) * max(half, floor)
    end, l1 = _cap(S[:, 0] - mid[0], slack, steps, floor)
    start, l0 = _cap(mid[0] - S[:, 0], slack, steps, floor)
    axis = axes[0]
    gc = GeneralizedCylinder.from_dict({
        "name": name,
        "curve": {"type": "bezier", "points": [(origin + (mid[0] - start) * axis).tolist(),
                                                (origin + (mid[0] + end) * axis).tolist()]},
        "up": axes[1].tolist(),
        "keys": [{"t": 0.0, "radii": [ry, rz], "twist": 0.0}],
        "caps": [l0 * (1.0 + margin), l1 * (1.0 + margin)],
    })
    for step in range(max_grow + 1):
        missed = int((~np.asarray(gc.contains(X))).sum())
        if missed == 0:
            if step:
                log.info("auto_gc %s: grew %d times to hold every vertex", name, step)
            return gc
        d = gc.to_dict()
        d["keys"] = [{**k, "radii": [r * 1.05 for r in k["radii"]]} for k in d["keys"]]
        d["caps"] = [c * 1.05 for c in d["caps"]]
        gc = GeneralizedCylinder.from_dict(d)
    raise DataError(f"automatic GC still misses {missed} of {len(X)} vertices after {max_grow} growth steps",
                    gc=name, fix="annotate this mesh by hand")


METHODS = ("skeleton", "axis")


@dataclass(frozen=True)
class AutoGCSettings:
    """How automatic GCs are made: keys of the `annotate` group, whose values live in
    conf/annotate/default.yaml (`from_yaml`, `from_config`). See that file for what each field
    means."""

    method: str
    max_gcs: int
    min_branch_length: float
    margin: float
    resolution: int
    skeleton: str
    n_keys: int
    samples: int
    seed: int
    protrusions: bool
    bulb_ratio: float
    up: str
    front: str

    def __post_init__(self):
        checks = {"method": self.method in METHODS, "max_gcs": self.max_gcs >= 1,
                  "min_branch_length": self.min_branch_length >= 0.0, "margin": self.margin >= 0.0,
                  "resolution": self.resolution >= 16, "n_keys": self.n_keys >= 2,
                  "samples": self.samples >= 100}
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"annotate.{name}",
                                fix=f"method one of {', '.join(METHODS)}; max_gcs >= 1; resolution "
                                    ">= 16; n_keys >= 2; samples >= 100; margin, min_branch_length >= 0")
        for name in ("up", "front"):
            parse_axis(getattr(self, name), f"annotate.{name}")

    @classmethod
    def from_yaml(cls, **overrides) -> "AutoGCSettings":
        """conf/annotate/default.yaml's values, some replaced by `overrides`."""
        return yaml_settings(cls, "annotate/default.yaml", **overrides)

    @classmethod
    def from_config(cls, d) -> "AutoGCSettings":
        """From the `annotate` group (or some of its keys; the rest: its YAML's); its keys that
        are not these settings' are the runner's or `TransferSettings`'; an unknown key is a
        DataError."""
        return from_group(cls, d, "annotate/default.yaml", field="annotate")


def auto_gcs(mesh: trimesh.Trimesh, settings: AutoGCSettings | None = None) -> list[GeneralizedCylinder]:
    """GCs for a normalised mesh by ``settings.method``."""
    settings = settings or AutoGCSettings.from_yaml()
    if settings.method == "axis":
        return [auto_gc(mesh, margin=settings.margin)]

    gcs, _ = skeleton_gcs(mesh, **{k: v for k, v in dataclasses.asdict(settings).items() if k != "method"})
    return gcs


def auto_annotation(mesh: str | os.PathLike, name: str | None = None, bound: float = 0.8,
                    settings: AutoGCSettings | None = None) -> Annotation:
    """Annotation with automatic GCs for a mesh file (or resource) that has none.

    The GCs are fitted to the normalised mesh, as annotation coordinates are normalised ones."""
    normalized, _, _ = normalize(load_mesh(mesh), bound)
    spec = str(mesh) if is_resource(str(mesh)) else os.path.abspath(mesh)
    if name is None:
        name = Path(spec.split(":", 1)[-1] if is_resource(spec) else spec).stem
    try:
        gcs = auto_gcs(normalized, settings)
    except DataError as e:
        if e.path is not None:
            raise
        raise DataError(e.what, path=spec, gc=e.gc, field=e.field, fix=e.fix) from None
    return Annotation(name=name, mesh=spec, gcs=gcs, bound=bound)
