"""Meshes of every shape in a trained auto-decoder (NGC per-GC codes or DeepSDF shape codes)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml
from tqdm import tqdm

from ngc_gen.geometry import GeneralizedCylinder

from .extractor import ExtractionResult, extract_mesh
from .rows import RowsFn
from .world import extract_world_mesh


def shape_gcs(shape_meta: dict) -> list[GeneralizedCylinder]:
    """The GCs of a shape recorded in a checkpoint's meta."""
    d = yaml.safe_load(shape_meta["annotation_yaml"])
    return [GeneralizedCylinder.from_dict(g) for g in d["gcs"]]


def ngc_sdf_fn(decoder, codes: torch.Tensor):
    """sdf_fn(gc_index, rel): the decoder with GC `gc_index`'s code (per-GC callers; wrap
    with `per_gc_rows` for `extract_mesh`)."""
    def fn(j: int, rel: torch.Tensor) -> torch.Tensor:
        return decoder(codes[j].expand(len(rel), -1), rel)
    return fn


def ngc_rows_fn(decoder, codes: torch.Tensor) -> RowsFn:
    """rows_fn(gc_index, rel) for `extract_mesh`: one batched decoder call across GCs
    (`NGCDecoder.sdf_rows`, end features once per GC), in inference mode."""
    codes = codes.detach()

    @torch.inference_mode()
    def fn(gc_index: torch.Tensor, rel: torch.Tensor) -> torch.Tensor:
        return decoder.sdf_rows(codes.to(rel.device), gc_index, rel)
    return fn


def extract_shape(module, index: int, resolution: int = 256, bound: float = 1.0,
                  chunk: int = 65536, gcs: list[GeneralizedCylinder] | None = None,
                  **kwargs) -> ExtractionResult:
    """Mesh of shape `index` of a trained AutoDecoder; `gcs` overrides the recorded GCs (edits)."""
    meta = module.hparams.meta["shapes"][index]
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]]
    with torch.inference_mode():
        if module.hparams.kind == "deepsdf":
            code = codes[0]
            return extract_world_mesh(
                lambda x: module.decoder(code.expand(len(x), -1), x), resolution, bound,
                chunk=chunk)
    return extract_mesh(gcs if gcs is not None else shape_gcs(meta),
                        ngc_rows_fn(module.decoder, codes), resolution, bound, chunk=chunk,
                        **kwargs)


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
        res = extract_shape(module, i, resolution, bound, chunk)
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
