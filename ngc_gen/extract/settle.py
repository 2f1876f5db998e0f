"""The last refinement level: settling points from the corners of their block (numba kernels).

A kept block of side 2 (cells) holds 8 child cells and 27 lattice points: its 8 corners (values
known) and 19 new ones, point j at HALF[j] in {0, 1, 2}^3. A new point lies between the 2, 4 or
8 corners whose coordinates agree with it on its even axes, at distance d = sqrt(number of odd
axes) cells from each. For GC i and the exact cell test of the last level (a corner in
N_i = {x in GC i : f_i(x) < tau} and a corner outside it) a point has two flags, "can be in N_i"
and "can be outside N_i", both exact at the corners. A new point is *settled* outside N_i when
every one of its corners lies inside GC i with f_i > tau + c d, so f_i > tau at the point for a
c-Lipschitz f_i; and settled inside when every one has f_i < -c d and lies deeper than c d in
the GC. Otherwise both flags are set until the point is evaluated.

State bits per point: CAN_NEG (may be in N_i), CAN_POS (may be outside), SURE (flags exact).
Cell status: DROP (no corner can be in N_i or none can be outside), KEEP (settled corners of
both kinds), UNDECIDED (depends on unsettled corners). Python loops here run over the 27 points
or 8 children of a block inside compiled kernels, never over blocks.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .marching import CORNERS
from .store import gallop

CAN_NEG, CAN_POS, SURE = 1, 2, 4
DROP, KEEP, UNDECIDED = 0, 1, 2

# point j of a block at HALF[j] (half steps); its block corners (CORNERS indices, -1 padded),
# their number and the point's number of odd axes; CELL[o, c]: point of corner c of child o
HALF = np.array([(a, b, c) for a in range(3) for b in range(3) for c in range(3)],
                dtype=np.int64)
_parents = [np.flatnonzero(np.all((p == 1) | (2 * CORNERS == p), 1)) for p in HALF]
PARENTS = np.full((27, 8), -1, dtype=np.int64)
for _j, _ps in enumerate(_parents):
    PARENTS[_j, :len(_ps)] = _ps
N_PARENTS = np.array([len(ps) for ps in _parents], dtype=np.int64)
N_ODD = (HALF == 1).sum(1).astype(np.int64)
CELL = ((CORNERS[:, None, :] + CORNERS[None, :, :]) @ np.array([9, 3, 1])).astype(np.int64)


@njit(cache=True)
def _flags(fv, mv, tau):
    """Exact state of an evaluated point (tau as float32: the comparisons of `exact_state`)."""
    inside = mv <= 1.0
    neg = inside and fv < tau
    pos = (not inside) or fv >= 0.0
    return (CAN_NEG if neg else 0) | (CAN_POS if pos else 0) | SURE


@njit(cache=True, parallel=True)
def settle_points(f, m, tau32, tau, r_min, reach, parents, n_parents, n_odd, state):
    """f, m (n, 8) float32 block corner values; reach[k] = c * spacing * sqrt(k) -> state
    (n, 27) uint8 (module docstring). tau32: tau as float32 for the exact corner flags."""
    for b in prange(f.shape[0]):
        for j in range(27):
            k = n_odd[j]
            if k == 0:
                o = parents[j, 0]
                state[b, j] = _flags(f[b, o], m[b, o], tau32)
                continue
            r = reach[k]
            above, deep = True, True
            for q in range(n_parents[j]):
                o = parents[j, q]
                fv, mv = f[b, o], m[b, o]
                inside = mv <= 1.0
                depth = (1.0 - math.sqrt(min(mv, 1.0))) * r_min
                above = above and inside and fv > tau + r
                deep = deep and inside and fv < -r and depth > r
            if above and not deep:
                state[b, j] = CAN_POS | SURE
            elif deep and not above:
                state[b, j] = CAN_NEG | SURE
            else:
                state[b, j] = CAN_NEG | CAN_POS


@njit(cache=True, parallel=True)
def cell_status(state, idx, last, corners, cell, status):
    """state (n, 27), block origins idx (n, 3), last cell index `last` -> status (n, 8) of the
    child cells (DROP outside the grid)."""
    for b in prange(state.shape[0]):
        for o in range(8):
            if (idx[b, 0] + corners[o, 0] > last or idx[b, 1] + corners[o, 1] > last
                    or idx[b, 2] + corners[o, 2] > last):
                status[b, o] = DROP
                continue
            neg, pos, sure = False, False, True
            for c in range(8):
                s = state[b, cell[o, c]]
                neg = neg or (s & CAN_NEG) != 0
                pos = pos or (s & CAN_POS) != 0
                sure = sure and (s & SURE) != 0
            status[b, o] = DROP if not (neg and pos) else (KEEP if sure else UNDECIDED)


@njit(cache=True, parallel=True)
def needed_points(state, status, cell, need):
    """need (n, 27) bool: the unsettled corners of UNDECIDED cells."""
    for b in prange(state.shape[0]):
        for o in range(8):
            if status[b, o] == UNDECIDED:
                for c in range(8):
                    j = cell[o, c]
                    if (state[b, j] & SURE) == 0:
                        need[b, j] = True


@njit(cache=True, parallel=True)
def decide_cells(state, status, cell):
    """UNDECIDED cells -> KEEP or DROP once every corner's state is SURE (in place)."""
    for b in prange(state.shape[0]):
        for o in range(8):
            if status[b, o] == UNDECIDED:
                neg, pos = False, False
                for c in range(8):
                    s = state[b, cell[o, c]]
                    neg = neg or (s & CAN_NEG) != 0
                    pos = pos or (s & CAN_POS) != 0
                status[b, o] = KEEP if (neg and pos) else DROP


@njit(cache=True, parallel=True)
def fill_exact(blocks, half_key, need, keys, f, m, tau32, state):
    """state[b, j] <- the exact state of point j of block b where need[b, j]: its key
    blocks[b] + half_key[j] is found in the sorted `keys`, whose values are f, m. Blocks come
    sorted, so for each j the keys come sorted too: a galloping pass per j."""
    for j in prange(27):
        lo = 0
        for b in range(blocks.shape[0]):
            if not need[b, j]:
                continue
            lo = gallop(keys, lo, blocks[b] + half_key[j])
            state[b, j] = _flags(f[lo], m[lo], tau32)


def exact_state(f: np.ndarray, m: np.ndarray, tau: float) -> np.ndarray:
    """Evaluated points (f, m) -> their SURE state bits (uint8)."""
    inside = m <= 1.0
    neg = inside & (f < tau)
    pos = ~inside | (f >= 0.0)
    return (neg * CAN_NEG | pos * CAN_POS | SURE).astype(np.uint8)
