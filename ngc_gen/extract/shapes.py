"""Meshes of every shape in a trained auto-decoder (NGC per-GC codes or DeepSDF shape codes)."""
from __future__ import annotations

import torch
import yaml

from ngc_gen.geometry import GeneralizedCylinder

from .extractor import ExtractionResult, extract_mesh
from .world import extract_world_mesh


def shape_gcs(shape_meta: dict) -> list[GeneralizedCylinder]:
    """The GCs of a shape recorded in a checkpoint's meta."""
    d = yaml.safe_load(shape_meta["annotation_yaml"])
    return [GeneralizedCylinder.from_dict(g) for g in d["gcs"]]


def ngc_sdf_fn(decoder, codes: torch.Tensor):
    """sdf_fn(gc_index, rel) for `extract_mesh`: the decoder with GC `gc_index`'s code."""
    def fn(j: int, rel: torch.Tensor) -> torch.Tensor:
        return decoder(codes[j].expand(len(rel), -1), rel)
    return fn


def extract_shape(module, index: int, resolution: int = 256, bound: float = 1.0,
                  chunk: int = 65536, gcs: list[GeneralizedCylinder] | None = None,
                  **kwargs) -> ExtractionResult:
    """Mesh of shape `index` of a trained AutoDecoder; `gcs` overrides the recorded GCs (edits)."""
    meta = module.hparams.meta["shapes"][index]
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]]
    with torch.no_grad():
        if module.hparams.kind == "deepsdf":
            code = codes[0]
            return extract_world_mesh(
                lambda x: module.decoder(code.expand(len(x), -1), x), resolution, bound,
                chunk=chunk)
        return extract_mesh(gcs if gcs is not None else shape_gcs(meta),
                            ngc_sdf_fn(module.decoder, codes), resolution, bound, chunk=chunk,
                            **kwargs)
