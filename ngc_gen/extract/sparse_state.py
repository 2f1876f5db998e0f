"""The sparse extractor's state (`sparse.py`): point keys on the padded lattice, each GC's
blocks and values while it is refined, and the field that evaluates the network on them."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ngc_gen.geometry import GeneralizedCylinder

from .grid import Grid
from .rows import RowQueue
from .marching import CORNERS
from .store import PointStore, find_sorted


class Keys:
    """Flat int64 keys of lattice indices (i, j, k), padded lattice of side Q = 2R. The map is
    linear, so a sorted array of keys shifted by an index offset stays sorted."""

    def __init__(self, resolution: int):
        self.Q = 2 * int(resolution)
        self.corner = self.encode(CORNERS)          # key offsets of the 8 corners at step 1

    def encode(self, idx: np.ndarray) -> np.ndarray:
        idx = np.asarray(idx, dtype=np.int64)
        return (idx[..., 0] * self.Q + idx[..., 1]) * self.Q + idx[..., 2]

    def decode(self, key: np.ndarray) -> np.ndarray:
        return np.stack([key // (self.Q * self.Q), (key // self.Q) % self.Q, key % self.Q], -1)

    def points(self, key: np.ndarray, grid: Grid) -> np.ndarray:
        """(n,) keys -> (n, 3) float64 world positions, `grid.coords` of each index."""
        out = np.empty((len(key), 3), dtype=np.float64)
        _key_points(np.ascontiguousarray(key, dtype=np.int64), self.Q, grid.axis(),
                    grid.bound, grid.spacing, out)
        return out


    def corner_runs(self, blocks: np.ndarray, step: int) -> list[np.ndarray]:
        """Sorted block keys -> 8 sorted arrays: the keys of each block's corner o."""
        return [blocks + step * off for off in self.corner]


@njit(cache=True, parallel=True)
def _key_points(key, Q, axis, bound, spacing, out):
    R = axis.shape[0]
    for n in prange(key.shape[0]):
        k = key[n]
        idx = (k // (Q * Q), (k // Q) % Q, k % Q)
        for a in range(3):
            i = idx[a]
            out[n, a] = axis[i] if i < R else -bound + i * spacing


@dataclass
class GCState:
    """One GC's refinement: its store of values, band top tau, smallest radius, block keys."""

    index: int
    gc: GeneralizedCylinder
    store: PointStore
    tau: float
    r_min: float
    blocks: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


def overlap_counts(gcs: list[GeneralizedCylinder]) -> np.ndarray:
    """(K,) 1 + the number of other GCs whose bounding box meets this GC's box."""
    if not gcs:
        return np.zeros(0, dtype=np.int64)
    lo = np.stack([g.bounds()[0] for g in gcs])
    hi = np.stack([g.bounds()[1] for g in gcs])
    meet = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), -1)
    return meet.sum(1)


def r_min(gc: GeneralizedCylinder) -> float:
    return float(min(min(min(k.radii) for k in gc.keys), *gc.caps))


class SparseField:
    """Evaluates GCs at lattice points into their stores, one batched network pass per call."""

    def __init__(self, grid: Grid, keys: Keys, queue_args: dict, stats: dict):
        self.grid, self.keys, self.queue_args, self.stats = grid, keys, queue_args, stats

    def ensure(self, states: list[GCState], keys_per_gc: list[np.ndarray]
               ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Sorted unique keys per GC -> (f, m) at them, from the stores; the missing ones get
        geometry, then the inside points of all GCs go through the network together."""
        t0 = time.perf_counter()
        out, todo = [], []
        for st, keys in zip(states, keys_per_gc):
            found, f, m = st.store.lookup(keys)
            out.append((f, m))
            miss = np.flatnonzero(~found)
            if len(miss) == 0:
                continue
            rel, mm = st.gc.relative_inside(self.keys.points(keys[miss], self.grid))
            inside = mm <= 1.0
            todo.append((st, keys, miss, rel[inside], inside, mm, f, m))
            self.stats["n_relative"] += len(miss)
        self.stats["seconds_geometry"] += time.perf_counter() - t0
        values = np.empty(sum(len(t[3]) for t in todo), dtype=np.float32)

        def sink(gc_index, where, v):
            values[where] = v

        queue = RowQueue(sink=sink, stats=self.stats, **self.queue_args)
        offset = 0
        for st, _, _, rel, _, _, _, _ in todo:
            queue.push(st.index, rel, np.arange(offset, offset + len(rel)))
            offset += len(rel)
        queue.flush()
        offset = 0
        for st, keys, miss, rel, inside, mm, f, m in todo:
            fm = np.full(len(miss), np.inf, dtype=np.float32)
            fm[inside] = values[offset:offset + len(rel)]
            offset += len(rel)
            f[miss], m[miss] = fm, mm
            st.store.add(keys[miss], fm, mm.astype(np.float32))
        return out


def positions(U: np.ndarray, runs: list[np.ndarray]) -> np.ndarray:
    """Sorted unique keys U, 8 sorted corner runs (each key in U) -> (n, 8) index of each
    corner in U (sorted needles: a galloping pass each)."""
    out = np.empty((len(runs[0]), len(runs)), dtype=np.int64)
    for o, r in enumerate(runs):
        out[:, o] = find_sorted(U, r)
    return out
