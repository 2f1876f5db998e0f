"""Which checkpoint a command means: edit.py, the editor and mix sources name a fit run, a
checkpoint file or a sample.py output folder; this resolves all three to one file."""
from __future__ import annotations

from pathlib import Path

from ngc_gen import workspace


def fit_checkpoint(run) -> Path:
    """The checkpoint edit.py reads: a fit run directory (its checkpoints/last.ckpt), a
    checkpoint file, or a sample.py output directory (its shapes.ckpt)."""
    from ngc_gen.lit.peek import resolve_checkpoint

    if run is not None and Path(run).is_dir() and (workspace.shapes_checkpoint(run)).is_file() \
            and not (workspace.checkpoints(run)).is_dir():
        return workspace.shapes_checkpoint(run)
    return resolve_checkpoint(run, what="fit run",
                              fix="pass run=<dir> (or its checkpoints/last.ckpt) of a `train.py "
                                  "stage=fit` run, or run=<a sample.py output directory>")
