"""The worker pool: tensors passed to workers and back do not each hold a file descriptor (300
animals' GCs and samples ran out of descriptors in shape-latent preparation)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

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
