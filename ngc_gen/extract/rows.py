"""Network rows: points of all GCs go to one callable with a GC index per row.

    rows_fn(gc_index (M,) int64, rel (M, 3) float32) -> (M,) float32

A `RowQueue` collects rows (from any GC, in any order) and sends them in calls of at most
`chunk` rows, so a call mixes GCs and only the very last call of an extraction is short. No row
is padding, unless `fixed_batch` asks for it: then every call gets exactly `chunk` rows (the
tail zero-padded, the padding dropped), so a row's value cannot depend on how many rows shared
its call (BLAS picks kernels by matrix shape); exactness tests use that, nothing else.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np
import torch

RowsFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]
SdfFn = Callable[[int, torch.Tensor], torch.Tensor]
Sink = Callable[[np.ndarray, object, np.ndarray], None]


def per_gc_rows(sdf_fn: SdfFn) -> RowsFn:
    """Adapter for the per-GC signature `sdf_fn(gc_index: int, rel (M, 3)) -> (M,)`: one call
    per GC present in the rows (for callers that build their field per GC)."""
    def rows_fn(gc_index: torch.Tensor, rel: torch.Tensor) -> torch.Tensor:
        out = torch.empty(len(rel), dtype=torch.float32, device=rel.device)
        for j in torch.unique(gc_index).tolist():
            sel = torch.nonzero(gc_index == j).squeeze(1)
            v = torch.as_tensor(sdf_fn(int(j), rel[sel])).detach()
            if v.numel() != len(sel):
                raise ValueError(f"sdf_fn(gc_index={j}, rel (M, 3)) must return M = {len(sel)} "
                                 f"values, got shape {tuple(v.shape)}")
            out[sel] = v.reshape(-1).to(device=out.device, dtype=torch.float32)
        return out
    return rows_fn


def new_stats() -> dict:
    return {"n_network_evals": 0, "n_network_rows": 0, "n_network_calls": 0,
            "n_relative": 0, "seconds_network": 0.0, "seconds_geometry": 0.0}


class RowQueue:
    """Rows waiting for the network. `push(gc_index, rel, payload)` queues rows (payload: a
    numpy array or a tensor per row, handed back to `sink`); full chunks go out at once,
    `flush()` sends the rest. sink(gc_index (n,) int64 numpy, payload[rows], values (n,)
    float32 numpy) sees rows in the order they were pushed."""

    def __init__(self, rows_fn: RowsFn, sink: Sink, stats: dict, chunk: int = 65536,
                 fixed_batch: bool = False, device=None):
        if int(chunk) < 1:
            raise ValueError(f"chunk must be a positive number of rows, got {chunk}")
        self.rows_fn, self.sink, self.stats = rows_fn, sink, stats
        self.chunk, self.fixed_batch, self.device = int(chunk), bool(fixed_batch), device
        self._gc: list[np.ndarray] = []
        self._rel: list[np.ndarray] = []
        self._payload: list = []
        self._n = 0

    def push(self, gc_index, rel: np.ndarray, payload) -> None:
        n = len(rel)
        if n == 0:
            return
        gc = np.broadcast_to(np.asarray(gc_index, dtype=np.int64), (n,))
        if self.fixed_batch and self._n and self._gc[-1][-1] != gc[0]:
            self.flush()                       # exactness mode: a call holds one GC's rows
        self._gc.append(gc)
        self._rel.append(np.asarray(rel, dtype=np.float32))
        self._payload.append(payload)
        self._n += n
        if self._n >= self.chunk:
            self._drain(final=False)

    def flush(self) -> None:
        if self._n:
            self._drain(final=True)

    def _drain(self, final: bool) -> None:
        gc, rel = np.concatenate(self._gc), np.concatenate(self._rel)
        payload = (torch.cat(self._payload) if isinstance(self._payload[0], torch.Tensor)
                   else np.concatenate(self._payload))
        c = self.chunk
        stop = len(gc) if final else (len(gc) // c) * c
        for s in range(0, stop, c):
            self.sink(gc[s:s + c], payload[s:s + c], self._call(gc[s:s + c], rel[s:s + c]))
        self._gc, self._rel, self._payload = [gc[stop:]], [rel[stop:]], [payload[stop:]]
        self._n = len(gc) - stop

    def _call(self, gc: np.ndarray, rel: np.ndarray) -> np.ndarray:
        n = len(gc)
        g, r = torch.from_numpy(np.ascontiguousarray(gc)), torch.from_numpy(rel)
        if self.fixed_batch and n < self.chunk:
            g = torch.cat([g, g.new_full((self.chunk - n,), int(gc[0]))])
            r = torch.cat([r, r.new_zeros(self.chunk - n, 3)])
        if self.device is not None:
            g, r = g.to(self.device), r.to(self.device)
        t0 = time.perf_counter()
        out = torch.as_tensor(self.rows_fn(g, r)).detach()
        self.stats["seconds_network"] += time.perf_counter() - t0
        if out.numel() != len(r):
            raise ValueError(f"rows_fn(gc_index (M,), rel (M, 3)) must return M = {len(r)} "
                             f"values, got shape {tuple(out.shape)}")
        out = out.reshape(-1)[:n].to(device="cpu", dtype=torch.float32).numpy()
        self.stats["n_network_evals"] += n
        self.stats["n_network_rows"] += len(r)
        self.stats["n_network_calls"] += 1
        bad = ~np.isfinite(out)
        if bad.any():
            raise ValueError(f"the network returned non-finite values (NaN/inf) for GC "
                             f"{int(gc[bad][0])} at {int(bad.sum())} points inside it; check "
                             "the network/checkpoint")
        return out
