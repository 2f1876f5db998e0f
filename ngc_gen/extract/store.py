"""Per-GC values at grid points, kept sparse, and the cache that carries them across edits.

A `PointStore` holds, for one GC at one grid (resolution, bound), the points where the GC was
looked at: sorted int64 keys (see `ngc_gen.extract.sparse.Keys`), the SDF value f (float32,
+inf outside the GC) and the inside measure m (float32, <= 1 inside, inf where the cover balls
ruled the point out). Queries and insertions come sorted, so both are sequential passes
(a galloping search from the previous hit; a merge; numba kernels).

`FieldCache` keeps stores keyed by the caller's GC key (the GC's parameters and code: whatever
changes the GC's field must change its key) at a (resolution, bound). After an edit only GCs with
new keys are evaluated; everything else is read back, and since a point's value does not depend
on which other points were evaluated with it (for a row-independent network), the result equals
a full re-extraction.
"""
from __future__ import annotations

from collections import OrderedDict
from typing import Hashable

import numpy as np
from numba import njit


def sorted_unique(a: np.ndarray) -> np.ndarray:
    """Sorted unique values of an int64 array (a stable sort: fast on concatenated sorted
    runs; numpy's hash-based unique is far slower on millions of keys)."""
    s = np.sort(a, kind="stable")
    if len(s) == 0:
        return s
    return s[np.concatenate([[True], s[1:] != s[:-1]])]


@njit(cache=True)
def gallop(hay, lo, x):
    """The first index >= lo with hay[index] >= x (len(hay) if none), hay sorted: doubling steps
    from lo, then bisection, so a run of increasing x costs O(log distance) each."""
    n = hay.shape[0]
    if lo >= n or hay[lo] >= x:
        return lo
    step, prev = 1, lo
    hi = lo + 1
    while hi < n and hay[hi] < x:
        prev = hi
        step *= 2
        hi = prev + step
    a, b = prev + 1, min(hi, n)
    while a < b:
        mid = (a + b) // 2
        if hay[mid] < x:
            a = mid + 1
        else:
            b = mid
    return a


@njit(cache=True)
def _find_sorted(hay, needles, out):
    """out[i] = index of needles[i] in hay, -1 if absent; both sorted, so each search gallops
    on from the previous hit: O(m log(n / m)) for m needles in n keys."""
    n = hay.shape[0]
    lo = 0
    for i in range(needles.shape[0]):
        lo = gallop(hay, lo, needles[i])
        out[i] = lo if lo < n and hay[lo] == needles[i] else -1


def find_sorted(hay: np.ndarray, needles: np.ndarray) -> np.ndarray:
    """Sorted int64 keys `hay`, sorted `needles` -> (m,) int64 index of each needle in hay, -1
    where absent."""
    out = np.empty(len(needles), dtype=np.int64)
    _find_sorted(np.ascontiguousarray(hay), np.ascontiguousarray(needles), out)
    return out


@njit(cache=True)
def _merge(ak, af, am, bk, bf, bm, ok, of, om):
    i = j = 0
    na, nb = ak.shape[0], bk.shape[0]
    for k in range(na + nb):
        if j >= nb or (i < na and ak[i] < bk[j]):
            ok[k], of[k], om[k] = ak[i], af[i], am[i]
            i += 1
        else:
            ok[k], of[k], om[k] = bk[j], bf[j], bm[j]
            j += 1


class PointStore:
    """Sorted keys (int64) with f (float32) and m (float32) per key."""

    def __init__(self):
        self.keys = np.zeros(0, dtype=np.int64)
        self.f = np.zeros(0, dtype=np.float32)
        self.m = np.zeros(0, dtype=np.float32)

    def __len__(self) -> int:
        return len(self.keys)

    def lookup(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """sorted keys (n,) -> found (n,) bool, f (n,), m (n,) (NaN where not found)."""
        f = np.full(len(keys), np.nan, dtype=np.float32)
        m = np.full(len(keys), np.nan, dtype=np.float32)
        if len(self.keys) == 0:
            return np.zeros(len(keys), dtype=bool), f, m
        pos = find_sorted(self.keys, keys)
        found = pos >= 0
        f[found], m[found] = self.f[pos[found]], self.m[pos[found]]
        return found, f, m

    def add(self, keys: np.ndarray, f: np.ndarray, m: np.ndarray) -> None:
        """Add sorted keys not yet in the store (a merge: one pass over both)."""
        if len(keys) == 0:
            return
        n = len(self.keys) + len(keys)
        k, fo, mo = (np.empty(n, dtype=np.int64), np.empty(n, dtype=np.float32),
                     np.empty(n, dtype=np.float32))
        _merge(self.keys, self.f, self.m, np.ascontiguousarray(keys, dtype=np.int64),
               np.ascontiguousarray(f, dtype=np.float32),
               np.ascontiguousarray(m, dtype=np.float32), k, fo, mo)
        self.keys, self.f, self.m = k, fo, mo

    @property
    def nbytes(self) -> int:
        return self.keys.nbytes + self.f.nbytes + self.m.nbytes


class FieldCache:
    """Per-GC `PointStore`s keyed by (gc_key, resolution, bound), least recently used first
    out once more than `max_entries` are held. Pass the same cache to successive
    `extract_mesh(..., cache=cache, gc_keys=keys)` calls; stats report hits and misses."""

    def __init__(self, max_entries: int = 256):
        if int(max_entries) < 1:
            raise ValueError(f"max_entries must be >= 1, got {max_entries}")
        self.max_entries = int(max_entries)
        self._stores: OrderedDict[tuple, PointStore] = OrderedDict()

    def __len__(self) -> int:
        return len(self._stores)

    def get(self, gc_key: Hashable, resolution: int, bound: float) -> tuple[PointStore, bool]:
        """The store for this GC at this grid (a new empty one on a miss) and whether it hit."""
        key = (gc_key, int(resolution), float(bound))
        try:
            hash(key)
        except TypeError:
            raise TypeError(f"gc_keys must be hashable (e.g. a tuple of the GC's parameters and "
                            f"code bytes), got {type(gc_key).__name__}") from None
        store = self._stores.get(key)
        hit = store is not None
        if not hit:
            store = self._stores[key] = PointStore()
        self._stores.move_to_end(key)
        while len(self._stores) > self.max_entries:
            self._stores.popitem(last=False)
        return store, hit

    def clear(self) -> None:
        self._stores.clear()

    @property
    def nbytes(self) -> int:
        return sum(s.nbytes for s in self._stores.values())
