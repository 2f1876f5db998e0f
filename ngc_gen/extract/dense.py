"""The reference paths: every grid point of each GC's bounding box ("prefiltered": relative
coordinates there, the network only at points inside the GC) or of the whole box ("dense": the
network at every grid point for every GC, masked by the same inside test afterwards).

Both fold each GC's values into one flat (R^3,) float32 grid in GC order (min or smooth-min),
or into the blended union (`BlendAccumulator`, the same GC order), +inf
where no GC holds a point; walking slabs keeps the coordinates' memory bounded. They are
what the sparse path must reproduce, and the world-space extractor's grid.
"""
from __future__ import annotations

import time

import numpy as np
from tqdm.auto import tqdm

from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.geometry.union import BlendAccumulator

from .fold import fold_into
from .grid import Grid, lattice_points, n_slabs, restrict, slabs
from .rows import RowQueue


def evaluate_grid(gcs: list[GeneralizedCylinder], grid: Grid, queue_args: dict, stats: dict,
                  smooth: float, prefilter: bool, slab_points: int = 1 << 18,
                  progress: bool | None = None, blend: float = 0.0,
                  blend_k: float = 0.0) -> np.ndarray:
    """-> (R^3,) float32 values, C order, +inf outside every GC. blend > 0: the blended union
    of that width and softness blend_k (`ngc_gen.geometry.union`) instead of the min /
    smooth-min."""
    acc = np.full(grid.n_points, np.inf, dtype=np.float32)
    mixed = BlendAccumulator(grid.n_points, blend, blend_k) if blend > 0 else None

    def sink(gc_index, payload, v):
        flat = payload if mixed is None else payload[:, 0].astype(np.int64)
        keep = flat >= 0                       # dense path: rows outside their GC
        gc_index, flat, v = gc_index[keep], flat[keep], v[keep]
        measure = None if mixed is None else payload[keep, 1]
        # rows come in push order: runs of one GC, folded one after another
        cut = np.flatnonzero(np.diff(gc_index)) + 1
        for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(gc_index)]):
            if mixed is None:
                fold_into(acc, flat[lo:hi], v[lo:hi], smooth)
            else:
                mixed.add(flat[lo:hi], v[lo:hi], measure[lo:hi])

    queue = RowQueue(sink=sink, stats=stats, **queue_args)
    regions = [restrict(grid.full(), grid.index_box(*gc.bounds())) if prefilter else grid.full()
               for gc in gcs]
    total = sum(n_slabs(r, slab_points) for r in regions)
    with tqdm(total=total, desc="extract", unit="slab", leave=False, delay=1.0,
              disable=None if progress is None else not progress) as bar:
        for j, (gc, region) in enumerate(zip(gcs, regions)):
            if region is None:
                continue
            for slab in slabs(region, slab_points):
                t0 = time.perf_counter()
                pts, flat = lattice_points(grid, slab)
                pts, flat = pts.numpy(), flat.numpy()
                if prefilter:
                    rel, m = gc.relative_inside(pts)
                    inside = m <= 1.0
                    rel, flat, m = rel[inside], flat[inside], m[inside]
                else:  # every point to the network; points outside the GC dropped afterwards
                    rel, m = gc.relative_inside(pts, cull=False)
                    flat = np.where(m <= 1.0, flat, -1)
                stats["n_relative"] += len(pts)
                stats["seconds_geometry"] += time.perf_counter() - t0
                payload = flat if mixed is None else np.stack(
                    [flat.astype(np.float64), m.astype(np.float32).astype(np.float64)], 1)
                queue.push(j, rel, payload)
                bar.update(1)
        queue.flush()
    return acc if mixed is None else mixed.result()
