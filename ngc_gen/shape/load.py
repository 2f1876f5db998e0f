"""Shapes from a trained auto-decoder (a `stage=fit` checkpoint, or a generation run's
`shapes.ckpt`, which has the same format)."""
from __future__ import annotations

import torch
import yaml

from ngc_gen.geometry import GeneralizedCylinder

from .shape import Shape


def recorded_gcs(shape_meta: dict) -> list[GeneralizedCylinder]:
    """The GCs of a shape recorded in a checkpoint's meta."""
    d = yaml.safe_load(shape_meta["annotation_yaml"])
    return [GeneralizedCylinder.from_dict(g) for g in d["gcs"]]


def recorded_union(hparams) -> dict:
    """Shape keyword arguments of a fit's recorded union (`model.union`: {kind: blend, width,
    k}): {blend, blend_k}, both 0 for the min and for checkpoints fitted before the union was
    recorded (they used the min)."""
    union = hparams.get("union") if hasattr(hparams, "get") else None
    if not union or union.get("kind", "min") == "min":
        return {"blend": 0.0, "blend_k": 0.0}
    return {"blend": float(union["width"]), "blend_k": float(union.get("k") or 0.0)}


def shapes_from_autodecoder(module) -> dict[str, Shape]:
    """{name: Shape} of every shape of a trained NGC AutoDecoder (codes detached)."""
    if module.hparams.kind != "ngc":
        raise ValueError(f"a {module.hparams.kind} model has no GCs: shapes need an NGC fit")
    out = {}
    for m in module.hparams.meta["shapes"]:
        codes = module.codes.weight[m["code_offset"]:m["code_offset"] + m["n_codes"]].detach()
        d = yaml.safe_load(m["annotation_yaml"])
        out[m["name"]] = Shape(recorded_gcs(m), codes.clone(), module.decoder, name=m["name"],
                               **recorded_union(module.hparams),
                               info={"mesh": d.get("mesh"), "frame": d.get("frame")})
    return out


def load_shapes(ckpt) -> dict[str, Shape]:
    """{name: Shape} from a fit checkpoint file or run directory (weights_only load)."""
    from ngc_gen.data.errors import DataError
    from ngc_gen.lit.checkpoint import load_autodecoder, resolve_checkpoint, FIT_FIX

    module = load_autodecoder(resolve_checkpoint(ckpt, FIT_FIX, "checkpoint"))
    if module.hparams.kind != "ngc":
        raise DataError(f"{ckpt} holds a {module.hparams.kind} model; shapes need NGC GCs",
                        fix="pass a checkpoint fitted with an NGC model (model=small or paper)")
    return shapes_from_autodecoder(module)


def autodecoder_mesh(module, index: int, resolution: int = 256, bound: float = 1.0,
                     chunk: int = 65536, gcs: list[GeneralizedCylinder] | None = None, **kwargs):
    """ExtractionResult of shape `index` of a trained AutoDecoder: an NGC shape through `Shape`
    (`gcs` overrides its GCs), a DeepSDF shape (one world-space code) over the box (densely, or
    coarse-to-fine with kwargs `coarse_step`, `lipschitz`: `extract_world_mesh`)."""
    meta = module.hparams.meta["shapes"][index]
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]]
    if module.hparams.kind == "deepsdf":
        from ngc_gen.extract.world import extract_world_mesh

        code = codes[0].detach()
        with torch.no_grad():
            return extract_world_mesh(lambda x: module.decoder(code.expand(len(x), -1), x),
                                      resolution, bound, chunk=chunk, **kwargs)
    shape = Shape(gcs if gcs is not None else recorded_gcs(meta), codes.detach().clone(),
                  module.decoder, name=meta["name"], **recorded_union(module.hparams))
    return shape.mesh(resolution, bound, chunk=chunk, **kwargs)
