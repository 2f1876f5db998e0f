"""Sparse multi-level extraction: work that follows the surface, not the volume (docs/extraction.md).

The field is F(x) = min (or smooth-min) of f_i(x) over the GCs i that contain x, a positive
background elsewhere; marching cubes only needs F at the corners of cells whose corners change
sign. Such a cell always has a corner in N_i = {x in GC i : f_i(x) < tau_i} and one outside
N_i's interior for some GC i (tau_i = 0 for the hard minimum; for a smooth minimum of width k,
tau_i = (n_i - 1) k / 4 with n_i the GCs that can overlap GC i, since folding n fields lowers
the minimum by at most (n - 1) k / 4). So each GC is refined on its own, from a coarse lattice
of blocks to single cells, keeping a block while it may hold a boundary point of N_i:

* the block comes within its half-diagonal of GC i's cover balls (exact test), and
* no corner lies inside GC i (a thin part may pass between the corners), or the corner
  values of f_i reach the band [-cD, tau_i + cD] (D the block diagonal, c the Lipschitz margin:
  a learned SDF is only roughly 1-Lipschitz), or some corner has f_i <= tau_i + cD while the
  GC's own boundary may cross the block (a corner outside it, or a corner within cD of it by
  the estimate (1 - sqrt(measure)) r_min); with all eight corners known, the band is cD / 2
  when every corner agrees (each point of a block is within D / 2 of its nearest corner);
* a block some GC j rules out as deep (inside GC j with f_j < 0 throughout) is dropped for
  every GC: the field, a minimum or smooth minimum never above f_j, is negative there;
* the last level (cells) is exact: a corner in N_i and a corner outside it. With `track` (the
  default) it visits only the kept blocks of side 2 whose own corners show that crossing, or
  have a corner within r = track_near c h of N_i's boundary by value (|f_i| < r or f_i < tau +
  r; h the grid spacing); on the fitted creature at 256 that is 23% of them. The surface
  through the others is grown from the cells found (`close_surface`). A visited block's new
  points are first settled from its corners where all of those corners agree (`finest_cells`,
  `settle`); only what is left is evaluated.

The cells kept by any GC are the active cells; F is completed at their corners with every GC
that contains them (values a GC's own refinement did not visit) and folded in GC order, so the
values equal those of the dense path, and `cells_mesh` gives the same triangles. Where a fitted
field is steeper than the margin a piece can be dropped; `close_surface` regrows every surface
component refinement touched. With `track` it is also what finds the surface in the blocks the
last level skips, so what can be missed is a component apart from the rest that crosses no
visited block: thinner than two cells, between the lattice points of side 2, and more than r
from N_i's boundary at all of them. bench/sparse_settings.py, 39 fitted shapes at 128 and 256:
with track_near = 0 six meshes lost a floater or a thin sheet next to the surface; 0.5 is the
smallest of 0, 0.1, 0.25, 0.5 that kept all six (chosen on them), and then every mesh is the
one `track = False` gives. `track = False` visits every block the margin keeps (slower).

Point keys: index (i, j, k) on a lattice padded past R - 1 (coarse blocks may reach beyond the
grid; their outer corners are ordinary points past the bound) -> (i Q + j) Q + k, Q = 2R.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from ngc_gen.conf.defaults import yaml_settings
from ngc_gen.geometry import GeneralizedCylinder

from . import settle
from .fold import fold
from .grid import Grid
from .marching import CORNERS, cells_mesh, crossing
from .sparse_state import GCState, Keys, SparseField, overlap_counts, positions, r_min
from .store import PointStore, sorted_unique


@dataclass(frozen=True)
class SparseSettings:
    """coarse_cells: blocks of the first level across the grid (its step is the power of two
    nearest (R - 1) / coarse_cells); lipschitz: c in |f| <= c D (>= 1, with margin); track:
    the last level visits only blocks whose corners cross N_i's boundary or lie within
    track_near x c x the grid spacing of it, and grows the surface from them (False: every
    block the margin keeps; module docstring)."""

    coarse_cells: int
    lipschitz: float
    track: bool
    track_near: float

    @classmethod
    def from_yaml(cls, **overrides) -> "SparseSettings":
        """The values of conf/extract/default.yaml's `sparse` (the one place they live), some
        replaced by `overrides`."""
        return yaml_settings(cls, "extract/default.yaml", "sparse", **overrides)

    def __post_init__(self):
        if int(self.coarse_cells) != self.coarse_cells or self.coarse_cells < 1:
            raise ValueError(f"coarse_cells must be a positive integer, got {self.coarse_cells!r}")
        if not self.lipschitz >= 1.0:
            raise ValueError(f"lipschitz margin must be >= 1 (1-Lipschitz SDF plus a margin), "
                             f"got {self.lipschitz!r}")
        if not self.track_near >= 0.0:
            raise ValueError(f"track_near must be >= 0 (a fraction of c x the grid spacing), "
                             f"got {self.track_near!r}")

    def track_reach(self, spacing: float) -> float | None:
        """The last level's reach around the band for blocks without a crossing (None: no
        tracking, every kept block is visited)."""
        return self.track_near * self.lipschitz * spacing if self.track else None

    def step(self, resolution: int) -> int:
        cells = max(resolution - 1, 1)
        return 2 ** max(0, round(math.log2(max(cells / self.coarse_cells, 1.0))))


def initial_blocks(st: GCState, grid: Grid, keys: Keys, step: int) -> np.ndarray:
    """Sorted keys of the blocks of side `step` over the GC's bounding box that come near its
    cover balls."""
    box = grid.index_box(*st.gc.bounds())
    if box is None:
        return np.zeros(0, dtype=np.int64)
    first, last = box
    last = np.minimum(last, grid.resolution - 2)         # first corner of a real cell
    if np.any(first > last):
        return np.zeros(0, dtype=np.int64)
    axes = [np.arange(first[a] // step, last[a] // step + 1) * step for a in range(3)]
    blocks = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    blocks = blocks[near(st, grid, blocks, step)]
    return keys.encode(blocks)                           # C order of the meshgrid: sorted


def near(st: GCState, grid: Grid, blocks: np.ndarray, step: int) -> np.ndarray:
    """Blocks (first corner indices (n, 3)) of side `step` that may meet the GC (centre within
    the half-diagonal of a cover ball)."""
    centre = -grid.bound + (blocks + 0.5 * step) * grid.spacing
    pad = 0.5 * step * grid.spacing * math.sqrt(3.0) * (1 + 1e-6) + 1e-9
    return st.gc.near(centre, pad)


def bounds_flags(f: np.ndarray, m: np.ndarray, st: GCState, cD):
    """Corner values and a reach cD (c times a distance; scalar or broadcastable) -> (above,
    deep): the corner lies in GC i and f_i is more than cD above the band there (f_i > tau
    within that distance), or more than cD below 0 while the corner is deeper than cD inside
    the GC (within that distance every point is inside with f_i < 0)."""
    inside = m <= 1.0
    depth = (1.0 - np.sqrt(np.minimum(m, 1.0))) * st.r_min
    above = inside & (f > st.tau + cD)
    deep = inside & (f < -cD) & (depth > cD)
    return above, deep


def keep_blocks(f: np.ndarray, m: np.ndarray, st: GCState, step: int, spacing: float,
                lipschitz: float) -> tuple[np.ndarray, np.ndarray]:
    """The refinement test of the module docstring for (n, 8) corner values -> (keep, deep)
    (n,) bool. A block is ruled out by one corner within its diagonal D, or by all eight
    corners within D / 2 (every point of a block is within half its diagonal of its nearest
    corner); `deep`: ruled out because it lies inside N_i with f_i < 0 throughout, so the
    field (a minimum or smooth minimum, never above f_i) is negative on the whole block.
    Blocks of side >= 2 go through one compiled pass (`bounds_flags` per corner, in float64)."""
    inside = m <= 1.0
    if step == 1:
        neg = inside & (f < st.tau)
        pos = ~inside | (f >= 0.0)
        return neg.any(1) & pos.any(1), np.zeros(len(f), dtype=bool)
    cD = lipschitz * step * spacing * math.sqrt(3.0)
    keep = np.empty(len(f), dtype=bool)
    deep = np.empty(len(f), dtype=bool)
    _keep_kernel(np.ascontiguousarray(f), np.ascontiguousarray(m), float(st.tau),
                 float(st.r_min), float(cD), keep, deep)
    return keep, deep


@njit(cache=True, parallel=True)
def _keep_kernel(f, m, tau, r_min, cD, keep, deep_out):
    """`keep_blocks` for blocks of side >= 2, one pass per block over its 8 corners."""
    for b in prange(f.shape[0]):
        n_in = 0
        fmin, fmax = np.inf, -np.inf
        above_any, above_h_all, deep_any, deep_h_all = False, True, False, True
        for o in range(8):
            mv, fv = float(m[b, o]), float(f[b, o])
            inside = mv <= 1.0
            if inside:
                n_in += 1
                fmin, fmax = min(fmin, fv), max(fmax, fv)
            depth = (1.0 - math.sqrt(min(mv, 1.0))) * r_min
            above_any |= inside and fv > tau + cD
            above_h_all &= inside and fv > tau + 0.5 * cD
            deep_any |= inside and fv < -cD and depth > cD
            deep_h_all &= inside and fv < -0.5 * cD and depth > 0.5 * cD
        kept = n_in == 0 or (fmin <= tau and fmax >= 0.0)  # crossing: kept even if not Lipschitz
        deep = not kept and not above_any and (deep_any or deep_h_all)
        kept = kept or not (above_any or above_h_all or deep)
        keep[b] = kept
        deep_out[b] = deep and not kept


def children(blocks: np.ndarray, f: np.ndarray, m: np.ndarray, st: GCState, step: int,
             grid: Grid, keys: Keys, lipschitz: float) -> tuple[np.ndarray, np.ndarray]:
    """Sorted keys of the half-size blocks of kept blocks (sorted keys, (n, 8) corner values)
    that hold a real cell, that their one known corner (child o shares corner o with its
    parent) does not rule out (`bounds_flags`), and that come near the GC; and the sorted
    keys of the children that corner rules out as deep (`keep_blocks`)."""
    half = step // 2
    cD = lipschitz * half * grid.spacing * math.sqrt(3.0)
    above, deep = bounds_flags(f, m, st, cD)
    runs, deep_runs = [], []
    for o, run in enumerate(keys.corner_runs(blocks, half)):
        runs.append(run[~(above[:, o] | deep[:, o])])
        deep_runs.append(run[deep[:, o] & ~above[:, o]])
    kids = np.sort(np.concatenate(runs), kind="stable")
    idx = keys.decode(kids)
    ok = np.all(idx <= grid.resolution - 2, 1)
    kids, idx = kids[ok], idx[ok]
    return kids[near(st, grid, idx, half)], np.sort(np.concatenate(deep_runs), kind="stable")


def inside_deep(blocks: np.ndarray, deep: dict[int, np.ndarray], keys: Keys) -> np.ndarray:
    """(n,) bool: the block (keys, any step) lies in a block some GC ruled out as deep (`deep`:
    step -> sorted unique keys; the blocks of a step sit on multiples of it)."""
    hit = np.zeros(len(blocks), dtype=bool)
    deep = {S: D for S, D in deep.items() if len(D)}
    if len(blocks) == 0 or not deep:
        return hit
    steps = np.array(list(deep), dtype=np.int64)
    starts = np.cumsum([0] + [len(D) for D in deep.values()])
    _inside_deep_kernel(np.ascontiguousarray(blocks, dtype=np.int64), keys.Q, steps, starts,
                        np.concatenate(list(deep.values())), hit)
    return hit


@njit(cache=True, parallel=True)
def _inside_deep_kernel(blocks, Q, steps, starts, deep, hit):
    for n in prange(blocks.shape[0]):
        k = blocks[n]
        i, j, l = k // (Q * Q), (k // Q) % Q, k % Q
        for s in range(steps.shape[0]):
            S = steps[s]
            key = ((i // S * S) * Q + j // S * S) * Q + l // S * S
            a, b = starts[s], starts[s + 1]
            p = a + np.searchsorted(deep[a:b], key)
            if p < b and deep[p] == key:
                hit[n] = True
                break


def finest_cells(field_: SparseField, states: list[GCState], parents: list, lipschitz: float,
                 stats: dict, track_reach: float | None) -> int:
    """The last level: each GC's kept blocks of side 2 (st.blocks, corner values in `parents`)
    -> st.blocks = its cells that hold a boundary point of N_i (the exact cell test of
    `keep_blocks` at step 1), evaluating only the points that test cannot do without.

    A new point p of a kept block (an edge midpoint, face centre or the centre) lies within
    d = 1, sqrt 2, sqrt 3 cells of the block corners it sits between (2, 4 or 8 of them). When
    every one of them lies inside GC i with f_i more than c d above the band (or every one more
    than c d below 0 and deeper than c d in the GC), p's side of N_i's boundary is settled
    (`settle`): neither its geometry nor the network is needed. One corner would do for a
    c-Lipschitz field, but fitted fields are steeper than c = 1.5 on a few percent of the grid
    edges near the surface (3-4% measured, up to 10x) and one corner then settles the single
    negative grid points of small floaters wrongly; all of them kept every mesh of
    bench/extract.py at 128 and 256 identical to the reference. A cell whose corners are all
    settled (or exact) is decided at once; only the unsettled corners of undecided cells are
    evaluated (geometry first: points outside the GC need no network), for all GCs in one
    pass. With `track_reach` = r (not None), only blocks with a corner in N_i and a corner
    outside it, or a corner inside GC i with -r < f_i < tau + r, are visited (the rest, and
    their corner values in `parents`, are dropped): the surface through the others is grown
    from these cells by `close_surface`. -> the number of candidate cells (children of the
    visited blocks inside the grid); stats get new_points (new points of the blocks, per
    block) and settled (those settled without evaluation)."""
    grid, keys = field_.grid, field_.keys
    half_key = keys.encode(settle.HALF)
    reach = lipschitz * grid.spacing * np.sqrt(np.arange(4.0))
    plans, want, n_cells = [], [], 0
    for n_gc, (st, (f, m)) in enumerate(zip(states, parents)):
        if track_reach is not None:
            inside = m <= 1.0
            cross = (inside & (f < st.tau)).any(1) & (~inside | (f >= 0.0)).any(1)
            near = inside & (f > -track_reach) & (f < st.tau + track_reach)
            visit = cross | near.any(1)
            st.blocks, f, m = st.blocks[visit], f[visit], m[visit]
            parents[n_gc] = (f, m)
        P = st.blocks
        n = len(P)
        state = np.empty((n, 27), dtype=np.uint8)
        status = np.empty((n, 8), dtype=np.uint8)
        if n:
            settle.settle_points(np.ascontiguousarray(f), np.ascontiguousarray(m),
                                 np.float32(st.tau), float(st.tau), float(st.r_min), reach,
                                 settle.PARENTS, settle.N_PARENTS, settle.N_ODD, state)
            idx = keys.decode(P)
            settle.cell_status(state, idx, grid.resolution - 2, CORNERS, settle.CELL, status)
            n_cells += int(np.prod(1 + (idx + 1 <= grid.resolution - 2), 1).sum())
        need = np.zeros((n, 27), dtype=bool)
        if n:
            settle.needed_points(state, status, settle.CELL, need)
        runs = [P[need[:, j]] + half_key[j] for j in range(27)]      # 27 sorted runs
        needed = sorted_unique(np.concatenate(runs))
        plans.append((P, state, status, need, needed))
        want.append(needed)
    new = np.flatnonzero(settle.N_ODD > 0)
    stats["settled"] = int(sum(np.count_nonzero(p[1][:, new] & settle.SURE) for p in plans))
    stats["new_points"] = int(sum(len(p[0]) for p in plans)) * len(new)
    got = field_.ensure(states, want)
    for st, (P, state, status, need, needed), (fU, mU) in zip(states, plans, got):
        if len(P) == 0:
            st.blocks = P
            continue
        settle.fill_exact(P, half_key, need, needed, fU, mU, np.float32(st.tau), state)
        settle.decide_cells(state, status, settle.CELL)
        keep = status == settle.KEEP
        st.blocks = np.sort(np.concatenate([P[keep[:, o]] + keys.corner[o] for o in range(8)]),
                            kind="stable")                   # 8 sorted runs: a merge
    return n_cells


def extract_sparse(gcs: list[GeneralizedCylinder], grid: Grid, stores: list[PointStore],
                   queue_args: dict, stats: dict, smooth: float, background: float,
                   settings: SparseSettings, keep_values: bool = False, blend: float = 0.0,
                   blend_k: float = 0.0):
    """-> (mesh, values or None). stats gain per-level counts. blend > 0: the blended union,
    whose value in a block another GC finds deep may still be positive (a weighted mean, not a
    minimum), so no GC drops another's blocks there; blend_k its softness."""
    union = (blend, blend_k)
    keys = Keys(grid.resolution)
    field_ = SparseField(grid, keys, queue_args, stats)
    counts = overlap_counts(gcs)
    states = [GCState(i, gc, stores[i], (counts[i] - 1) * smooth / 4.0, r_min(gc))
              for i, gc in enumerate(gcs)]
    step = settings.step(grid.resolution)
    stats.update(coarse_step=step, levels=[])
    for st in states:
        st.blocks = initial_blocks(st, grid, keys, step)
    deep: dict[int, list[np.ndarray]] = {}     # blocks inside some N_i with f_i < 0

    def drop_deep(parents=None):   # another GC's deep block: the field is negative there
        if blend > 0:
            return
        merged = {S: sorted_unique(np.concatenate(D)) for S, D in deep.items()}
        for n, st in enumerate(states):
            ok = ~inside_deep(st.blocks, merged, keys)
            st.blocks = st.blocks[ok]
            if parents is not None:
                parents[n] = (parents[n][0][ok], parents[n][1][ok])

    while True:
        t0 = time.perf_counter()
        evals0 = stats["n_network_evals"]
        if deep:
            drop_deep()
        runs = [keys.corner_runs(st.blocks, step) for st in states]
        U = [sorted_unique(np.concatenate(r)) for r in runs]
        got = field_.ensure(states, U)
        n_blocks, n_kept, parents = 0, 0, []
        for st, r, u, (fU, mU) in zip(states, runs, U, got):
            pos = positions(u, r)
            f, m = fU[pos], mU[pos]
            keep, deep_out = keep_blocks(f, m, st, step, grid.spacing, settings.lipschitz)
            deep.setdefault(step, []).append(st.blocks[deep_out])
            n_blocks += len(st.blocks)
            n_kept += int(keep.sum())
            st.blocks = st.blocks[keep]
            if step > 2:
                st.blocks, deep_kids = children(st.blocks, f[keep], m[keep], st, step, grid,
                                                keys, settings.lipschitz)
                deep.setdefault(step // 2, []).append(deep_kids)
            elif step == 2:
                parents.append((f[keep], m[keep]))
        stats["levels"].append({"step": step, "blocks": n_blocks, "kept": n_kept,
                                "network_evals": stats["n_network_evals"] - evals0,
                                "seconds": time.perf_counter() - t0})
        if step == 2:
            t0 = time.perf_counter()
            evals0 = stats["n_network_evals"]
            level = {"step": 1}
            drop_deep(parents)        # blocks of side 2 that another GC found deep at this step
            n_cells = finest_cells(field_, states, parents, settings.lipschitz, level,
                                   settings.track_reach(grid.spacing))
            drop_deep()
            level.update(blocks=n_cells, kept=sum(len(st.blocks) for st in states),
                         network_evals=stats["n_network_evals"] - evals0,
                         seconds=time.perf_counter() - t0)
            stats["levels"].append(level)
        if step <= 2:
            break
        step //= 2

    return complete_and_mesh(field_, states, keys, grid, stats, smooth, background,
                             keep_values, union)


def complete_and_mesh(field_: SparseField, states: list[GCState], keys: Keys, grid: Grid,
                      stats: dict, smooth: float, background: float, keep_values: bool,
                      union: tuple[float, float] = (0.0, 0.0)):
    """After the refinement: the active cells of all GCs, F at their corners from every GC
    holding them (union: the blend's width and softness, `field_values`), the surface closed,
    marching cubes. -> (mesh, values or None)."""
    t0 = time.perf_counter()
    evals0 = stats["n_network_evals"]
    cells = sorted_unique(np.concatenate([st.blocks for st in states]
                                         + [np.zeros(0, dtype=np.int64)]))
    points = sorted_unique(np.concatenate(keys.corner_runs(cells, 1)))
    F = field_values(field_, states, points, smooth, background, union)
    stats.update(completion_network_evals=stats["n_network_evals"] - evals0,
                 seconds_completion=time.perf_counter() - t0)
    t0 = time.perf_counter()
    evals0 = stats["n_network_evals"]
    cells, points, F, rounds = close_surface(field_, states, cells, points, F, smooth,
                                             background, union)
    stats.update(repair_rounds=rounds, repair_network_evals=stats["n_network_evals"] - evals0,
                 seconds_repair=time.perf_counter() - t0)
    corner_vals = F[positions(points, keys.corner_runs(cells, 1))]
    stats.update(n_active_cells=len(cells), n_corner_points=len(points),
                 n_covered=int((F != np.float32(background)).sum()))
    t0 = time.perf_counter()
    mesh = cells_mesh(keys.decode(cells), corner_vals, grid)
    stats["seconds_marching"] = time.perf_counter() - t0
    values = None
    if keep_values:
        R = grid.resolution
        pidx = keys.decode(points)
        values = np.full((R, R, R), np.nan, dtype=np.float32)
        values[pidx[:, 0], pidx[:, 1], pidx[:, 2]] = F
    return mesh, values


def field_values(field_: SparseField, states: list[GCState], points: np.ndarray, smooth: float,
                 background: float, union: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """F at sorted unique point keys: every GC whose box holds a point, folded in GC order;
    the background where no GC holds it. union: (blend width, blend softness), (0, 0) for
    the min / smooth min."""
    grid, keys = field_.grid, field_.keys
    lo = np.zeros((len(states), 3), dtype=np.int64)
    hi = np.full((len(states), 3), -1, dtype=np.int64)             # empty box: holds nothing
    for n, st in enumerate(states):
        box = grid.index_box(*st.gc.bounds())
        if box is not None:
            lo[n], hi[n] = box
    want = np.empty((len(states), len(points)), dtype=bool)
    _in_boxes(np.ascontiguousarray(points, dtype=np.int64), keys.Q, lo, hi, want)
    got = field_.ensure(states, [points[sel] for sel in want])
    vals, ins, ms = [], [], []
    for sel, (f, m) in zip(want, got):
        v = np.full(len(points), np.inf, dtype=np.float32)
        v[sel] = f
        i = np.zeros(len(points), dtype=bool)
        i[sel] = m <= 1.0
        mm = np.full(len(points), np.inf, dtype=np.float32)
        mm[sel] = m
        vals.append(v)
        ins.append(i)
        ms.append(mm)
    F = (fold(vals, ins, smooth, union[0], ms, union[1]) if states
         else np.full(len(points), np.inf, np.float32))
    return np.where(np.isfinite(F), F, np.float32(background)).astype(np.float32)


@njit(cache=True, parallel=True)
def _in_boxes(key, Q, lo, hi, out):
    """out[g, n]: point key[n] lies in the inclusive index box [lo[g], hi[g]]."""
    for n in prange(key.shape[0]):
        k = key[n]
        i, j, l = k // (Q * Q), (k // Q) % Q, k % Q
        for g in range(lo.shape[0]):
            out[g, n] = (lo[g, 0] <= i <= hi[g, 0] and lo[g, 1] <= j <= hi[g, 1]
                         and lo[g, 2] <= l <= hi[g, 2])


# faces of a cell: (axis, side) -> the 4 corners (CORNERS indices) on that face
FACES = [(a, side, np.flatnonzero(CORNERS[:, a] == side)) for a in range(3) for side in (0, 1)]


def close_surface(field_: SparseField, states: list[GCState], cells: np.ndarray,
                  points: np.ndarray, F: np.ndarray, smooth: float, background: float,
                  union: tuple[float, float] = (0.0, 0.0)):
    """Grow the active cells until the surface is closed: a crossing cell whose face has
    corners of both signs shares that face's crossing edges with the cell across it, which
    therefore holds surface too. A learned SDF is not exactly Lipschitz, so refinement can drop
    such a cell; this puts it back (one ring per round), so every surface component refinement
    touched comes out whole. -> (cells, points, F, rounds)."""
    grid, keys = field_.grid, field_.keys
    frontier = cells
    rounds = 0
    step_key = [keys.encode(np.eye(3, dtype=np.int64)[a]) for a in range(3)]
    while len(frontier):
        v = F[positions(points, keys.corner_runs(frontier, 1))]
        cross = crossing(v)
        frontier, v = frontier[cross], v[cross]
        idx = keys.decode(frontier)
        new = []
        for a, side, corners in FACES:
            below = (v[:, corners] < 0).sum(1)
            mixed = (below > 0) & (below < 4)
            nb_idx = idx[:, a] + (1 if side else -1)
            ok = mixed & (nb_idx >= 0) & (nb_idx <= grid.resolution - 2)
            new.append(frontier[ok] + (step_key[a] if side else -step_key[a]))
        cand = sorted_unique(np.concatenate(new))
        pos = np.minimum(np.searchsorted(cells, cand), max(len(cells) - 1, 0))
        frontier = cand[cells[pos] != cand] if len(cells) else cand
        if len(frontier) == 0:
            break
        rounds += 1
        cells = np.sort(np.concatenate([cells, frontier]), kind="stable")
        corner_pts = sorted_unique(np.concatenate(keys.corner_runs(frontier, 1)))
        pos = np.minimum(np.searchsorted(points, corner_pts), len(points) - 1)
        fresh = corner_pts[points[pos] != corner_pts]
        if len(fresh):
            Fn = field_values(field_, states, fresh, smooth, background, union)
            order = np.argsort(np.concatenate([points, fresh]), kind="stable")
            points = np.concatenate([points, fresh])[order]
            F = np.concatenate([F, Fn])[order]
    return cells, points, F, rounds
