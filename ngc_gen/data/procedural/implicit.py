"""Small implicit-modelling toolkit for procedural shapes: non-elliptic profiles, smooth union,
and a watertight single-piece mesh from a sampled field.

Used by the procedural creatures (``ngc_gen.data.procedural.creatures``); kept separate because nothing in
it knows about creatures. Convention: fields are negative inside, positive outside.
"""
from __future__ import annotations

import numpy as np
import trimesh

from ngc_gen.data.errors import DataError
from ngc_gen.extract.marching import marching_cubes_grid


def profile_norm(alpha: np.ndarray, beta: np.ndarray, exponent: float = 2.0,
                 lobes: int = 0, lobe_amp: float = 0.0, phase: float = 0.0) -> np.ndarray:
    """Gauge of a lobed superellipse at (alpha, beta): <= 1 inside, 1 on the boundary.

    The boundary is ``(|a|^p + |b|^p)^(1/p) = 1 + c cos(k theta + phase)``, theta = atan2(b, a):
    p != 2 makes rounded boxes (p > 2) or diamonds (p < 2), the cosine adds k lobes. Neither is an
    ellipse, which is the point: an elliptic GC alone cannot represent such cross-sections.
    """
    p = float(exponent)
    n = (np.abs(alpha) ** p + np.abs(beta) ** p) ** (1.0 / p)
    if lobes and lobe_amp:
        n = n / (1.0 + lobe_amp * np.cos(lobes * np.arctan2(beta, alpha) + phase))
    return n


def profile_envelope(exponent: float, lobe_amp: float = 0.0) -> float:
    """Largest Euclidean radius of the unit profile of ``profile_norm``: the factor by which an
    ellipse with the profile's radii must grow to enclose it (2^(1/2-1/p) at the diagonal for
    p > 2, times 1 + c for lobes)."""
    p = float(exponent)
    return max(1.0, 2.0 ** (0.5 - 1.0 / p)) * (1.0 + abs(lobe_amp))


def grid_axes(lo: np.ndarray, hi: np.ndarray, resolution: int) -> tuple[list[np.ndarray], float]:
    """Axes of a cubic-voxel grid covering [lo, hi] with `resolution` cells along its longest
    side: (list of 3 coordinate arrays, voxel size)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    h = float((hi - lo).max()) / resolution
    counts = np.ceil((hi - lo) / h).astype(int) + 1
    return [lo[i] + h * np.arange(counts[i]) for i in range(3)], h


def block_points(axes: list[np.ndarray], lo: np.ndarray, hi: np.ndarray):
    """The grid sub-block inside the box [lo, hi]: (tuple of slices, (M, 3) points in C order).

    Evaluating a part only inside its own box is the GC bounding-box prefilter of the paper."""
    sl = []
    for ax, a, b in zip(axes, lo, hi):
        i0 = int(np.searchsorted(ax, a, side="left"))
        i1 = int(np.searchsorted(ax, b, side="right"))
        sl.append(slice(max(i0, 0), min(i1, len(ax))))
    sub = [ax[s] for ax, s in zip(axes, sl)]
    pts = np.stack(np.meshgrid(*sub, indexing="ij"), -1).reshape(-1, 3)
    return tuple(sl), pts


def mesh_from_field(field: np.ndarray, origin: np.ndarray, voxel: float,
                    max_dropped_area: float = 1e-3) -> trimesh.Trimesh:
    """Zero level set of a grid field (negative inside) as a watertight single-piece mesh.

    Marching cubes (scikit-image, Lewiner), outward-facing triangles, largest connected piece
    kept. Raises DataError if the field is not positive on the grid border (the surface would be
    cut open), if the mesh is not watertight, or if the pieces dropped hold more than
    `max_dropped_area` of the area (a part came loose instead of a speck of noise)."""
    border = np.concatenate([field[[0, -1]].ravel(), field[:, [0, -1]].ravel(),
                             field[:, :, [0, -1]].ravel()])
    if not (border > 0).all():
        raise DataError("the implicit surface reaches the grid border",
                        fix="pad the grid so the whole shape lies strictly inside it")
    mesh = marching_cubes_grid(field, origin, voxel, float32_spacing=True)
    pieces = mesh.split(only_watertight=False)
    if len(pieces) > 1:
        areas = np.array([p.area for p in pieces])
        if 1.0 - areas.max() / areas.sum() > max_dropped_area:
            raise DataError(f"the shape falls apart into {len(pieces)} pieces "
                            f"(areas {np.round(np.sort(areas)[::-1], 5).tolist()})",
                            fix="make the parts overlap so their union is connected")
        mesh = pieces[int(areas.argmax())]
    if mesh.volume < 0:
        mesh.invert()
    if not mesh.is_watertight or not mesh.is_winding_consistent:
        raise DataError("marching cubes produced a mesh that is not watertight",
                        fix="raise the grid resolution or thicken thin parts")
    return mesh
