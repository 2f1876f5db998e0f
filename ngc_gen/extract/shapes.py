"""Meshes of every shape in a trained auto-decoder, scored against their ground truth (a runner:
writes files and computes metrics)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml
from tqdm import tqdm

from ngc_gen.shape import autodecoder_mesh


def reconstruct(module, out_dir: Path, gt: dict, resolution: int = 256, bound: float = 1.0,
                chunk: int = 65536, seed: int = 0) -> dict:
    """Extract every shape into out_dir/<name>.ply and score it against its ground truth
    gt[name] = (vertices, faces) in the normalised frame. Returns {shapes, mean}."""
    from ngc_gen.eval import reconstruction_metrics

    from ngc_gen.data.atomic import atomic_write

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    per = {}
    shapes = module.hparams.meta["shapes"]
    for i, meta in enumerate(tqdm(shapes, desc="extract", unit="shape", disable=len(shapes) < 2)):
        res = autodecoder_mesh(module, i, resolution, bound, chunk)
        atomic_write(out_dir / f"{meta['name']}.ply",
                     lambda f, m=res.mesh: f.write(m.export(file_type="ply")))
        V, F = gt[meta["name"]]
        m = reconstruction_metrics(res.mesh, trimesh.Trimesh(V, F, process=False), seed=seed)
        m.update(n_network_evals=int(res.stats["n_network_evals"]),
                 extract_s=float(res.stats["seconds"]))
        per[meta["name"]] = {k: (float(v) if isinstance(v, (float, np.floating)) else v)
                             for k, v in m.items()}
    keys = [k for k, v in next(iter(per.values())).items()
            if isinstance(v, (int, float)) and not isinstance(v, bool)]
    mean = {k: float(np.mean([p[k] for p in per.values()])) for k in keys}
    mean["watertight"] = float(np.mean([bool(p.get("watertight")) for p in per.values()]))
    return {"shapes": per, "mean": mean, "resolution": resolution}
