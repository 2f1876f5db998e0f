"""The worker pool: tensors passed to workers and back do not each hold a file descriptor (300
animals' GCs and samples ran out of descriptors in shape-latent preparation)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from ..helpers import ROOT

SCRIPT = textwrap.dedent("""
    import resource
    import torch
    from ngc_gen.data.workers import map_shapes

    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (256, hard))
    if __name__ == "__main__":
        items = [torch.full((4,), float(i)) for i in range(600)]
        out = list(map_shapes(torch.sum, items, workers=2))
        assert [float(x) for x in out] == [4.0 * i for i in range(600)]
        print("ok")
""")


def test_many_tensors_through_the_pool_stay_under_a_small_descriptor_limit(tmp_path):
    script = tmp_path / "pool.py"
    script.write_text(SCRIPT)
    r = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True,
                       timeout=240)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]



def _blas_threads(_) -> int:
    """In a worker: the threads numpy's OpenBLAS would use (its own query)."""
    import ctypes
    import glob
    import os

    import numpy as np

    for path in glob.glob(os.path.join(os.path.dirname(np.__file__), "..", "numpy.libs",
                                       "*openblas*")):
        lib = ctypes.CDLL(path)
        for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_",
                     "openblas_get_num_threads"):
            if hasattr(lib, name):
                return int(getattr(lib, name)())
    pytest.skip("numpy's BLAS here is no OpenBLAS")


def test_workers_run_numpys_blas_on_one_thread(monkeypatch):
    """OpenBLAS threads spinning on the other worker's core cost a transfer 1.4x the time."""
    import os

    from ngc_gen.data.workers import ONE_THREAD_ENV, map_shapes

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    assert list(map_shapes(_blas_threads, [0, 1], workers=2)) == [1, 1]
    assert not any(k in os.environ for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"))
    assert ONE_THREAD_ENV["OPENBLAS_NUM_THREADS"] == "1"
