"""A folder of randomly turned animals goes from `stage=annotate` to `stage=shape_latent` with
the README's commands only: each mesh written in the template's frame (one `up` per GC across
the folder), a line per mesh, the next command last; a frame override naming an axis that does
not exist is one line and exit 2 with the rest of the folder annotated; a user's YAML beside a
mesh is kept."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ngc_gen.data.annotations import load_annotation

from ..data.autogc.shapes import quadruped
from ..helpers import ROOT, run_entry

TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
SMALL = ["annotate.resolution=64", "annotate.samples=5000", "annotate.refine_steps=20"]


@pytest.mark.slow  # two annotate runs and a short shape-latent fit as a user runs them, ~3 min
def test_a_turned_folder_trains_with_the_readme_commands(tmp_path):
    d = tmp_path / "meshes"
    d.mkdir()
    for i, (name, kw) in enumerate((("cow", {}), ("dachshund", dict(length=1.0, leg=0.6)))):
        quadruped(rotation=Rotation.random(random_state=10 + i).as_matrix(), **kw)[0] \
            .export(d / f"{name}.ply")
    quadruped()[0].export(d / "pig.ply")
    (d / "frames.yaml").write_text("pig: {up: +w, front: +z}\n")
    mine = "# my own\nname: x\n"
    run = tmp_path / "annotate"
    r = run_entry("train.py", "stage=annotate", "data=folder", f"data.path={d}",
                  f"annotate.template={TEMPLATE}", f"hydra.run.dir={run}", *SMALL)
    assert r.returncode == 2, r.stderr[-3000:]
    assert "frame.up" in r.stderr and len(r.stderr.strip().splitlines()[-1]) > 0
    assert not (run / "pig.yaml").exists()
    out = r.stdout.splitlines()
    assert any(x.startswith("cow: ") for x in out) and any(x.startswith("pig: refused") for x in out)
    nxt = [x for x in out if x.startswith("next: ")]
    assert nxt and f"data.path={run}" in nxt[0]
    anns = [load_annotation(run / f"{n}.yaml") for n in ("cow", "dachshund")]
    ups = [[g.to_dict()["up"] for g in a.gcs] for a in anns]
    assert np.allclose(ups[0], ups[1]) and all(a.frame["source"] == "detected" for a in anns)
    # the README's next command, as printed
    (d / "cow.yaml").write_text(mine)  # a user's file beside a mesh is never touched
    r = run_entry("train.py", *nxt[0].split()[3:], "model=small", "trainer.max_steps=3",
                  "shape_latent.latent_dim=8", "shape_latent.preview=0", "batch_size=512",
                  "prepare.n_samples=4000", "prepare.coverage_samples=4000", "threads=1",
                  f"prepare.cache_dir={tmp_path}/prepared", f"hydra.run.dir={tmp_path}/sl")
    assert r.returncode == 0, r.stderr[-3000:]
    assert (d / "cow.yaml").read_text() == mine
