"""Independent per-shape work (building a creature, preparing a shape's samples) spread over
worker processes: each shape costs about a second of numpy, numba and torch on one thread, so
two processes finish a 48-shape dataset in about half the time of one.

Spawned, not forked: the parent may already run OpenMP and numba threads, which do not survive
a fork. Each worker computes with one thread; results come back in input order. One thread
includes the BLAS under numpy and scipy and libigl's loops: they read their thread count from
the environment when they load (ONE_THREAD_ENV, set for the spawned workers only). Left at one
thread per core, OpenBLAS's threads spin while they wait, on the core the other worker needs:
a template transfer took 1.4x the processor time, for no gain in wall time.
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Callable, Iterator

#: the thread counts a spawned worker's libraries read from the environment as they load
ONE_THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                  "IGL_NUM_THREADS": "1"}


def _share_by_file() -> None:
    """Tensors crossing processes are shared through files, not file descriptors: by default
    every shared storage keeps a descriptor open while it lives, and 300 animals' GCs and
    samples passed one way and back ran past a 20000-descriptor limit (torch's documented
    remedy for 'Too many open files')."""
    import torch.multiprocessing

    torch.multiprocessing.set_sharing_strategy("file_system")


def _one_thread() -> None:
    """The initializer of each worker process."""
    import numba
    import torch

    torch.set_num_threads(1)  # in a worker process we spawned
    numba.set_num_threads(1)
    _share_by_file()


@contextmanager
def _worker_env():
    """ONE_THREAD_ENV in this process's environment while workers are spawned (they inherit
    it), restored afterwards."""
    before = {k: os.environ.get(k) for k in ONE_THREAD_ENV}
    os.environ.update(ONE_THREAD_ENV)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def default_workers() -> int:
    """One worker per core."""
    return os.cpu_count() or 1


def worker_count(n_items: int, workers: int | None = None, min_items: int = 8) -> int:
    """The processes `map_shapes` uses for `n_items` items (1: this process)."""
    if workers is None:
        workers = default_workers() if n_items >= min_items else 1
    return int(workers) if n_items >= 2 else 1


def map_shapes(fn: Callable, items: list, workers: int | None = None,
               min_items: int = 8) -> Iterator:
    """`map(fn, items)`, in `workers` spawned processes, else in this process. `workers` None:
    one per core when there are at least `min_items` items (a spawned worker takes ~5 s to
    import torch and numba: fewer shapes are done sooner here). `fn` must be module-level."""
    workers = worker_count(len(items), workers, min_items)
    if workers <= 1:
        yield from map(fn, items)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    _share_by_file()

    with _worker_env(), ProcessPoolExecutor(min(workers, len(items)),
                                            mp_context=multiprocessing.get_context("spawn"),
                                            initializer=_one_thread) as pool:
        yield from pool.map(fn, items)
