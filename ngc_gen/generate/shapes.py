"""Decoded shapes: GCs + per-GC codes from latents, their meshes, and the files that make a
generated shape editable (mesh PLY, GC annotation YAML, fit-style checkpoint for edit.py).

Output frame: a decoded shape is mapped, mesh and GCs together, by the similarity that
`normalize: {bound: 0.8}` applies to the mesh (bounding box centred, longest side 1.6), so
loading the YAML and normalising its mesh is the identity (as for the training creatures).
Relative coordinates are invariant under that map, so the codes stay valid.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml

from ngc_gen.data.annotations import rounded_gc_dict, similar_gc_dict
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.mesh.io import normalize
from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.shape import Shape

BOUND = 0.8


@torch.no_grad()
def decode_shapes(module, latents: torch.Tensor, names: list[str]) -> list[Shape]:
    """Latents (B, D) through a ShapeLatentModule's shape decoder -> Shapes (decoded GCs and
    codes, the module's NGC decoder; info["latent"] holds the latent)."""
    latents = torch.as_tensor(latents, dtype=torch.float32)
    theta, codes = module.decode(latents)
    return [Shape([GeneralizedCylinder.from_dict(d) for d in module.template.gc_dicts(t)],
                  c.detach().clone(), module.ngc, name=n, info={"latent": s.detach().clone()})
            for n, s, t, c in zip(names, latents, theta, codes)]


def auto_chunk(resolution: int) -> int:
    """Network rows per call for a grid: extraction pads every call to `chunk` rows (bit-exact
    values whatever the batch), so keep it near the number of grid points a GC holds:
    resolution^3 / 128 within [2048, 65536] (16384 at 128^3)."""
    return int(min(65536, max(2048, int(resolution) ** 3 // 128)))


def normalise(mesh: trimesh.Trimesh, gcs: list[dict], bound: float = BOUND):
    """Map mesh and GC dicts by x -> (x - center) * scale, the similarity `normalize` applies to
    the mesh (`ngc_gen.data.mesh.io.normalize`). An empty mesh is returned unchanged (scale 1)."""
    if len(mesh.vertices) == 0:
        return mesh, gcs, np.zeros(3), 1.0
    out, center, scale = normalize(mesh, bound)
    return out, [similar_gc_dict(d, center, scale) for d in gcs], center, scale


def annotation_yaml(name: str, mesh: str, gcs: list[dict], bound: float | None = BOUND,
                    frame: tuple | None = None, body: dict | None = None) -> str:
    """Annotation YAML of docs/gcs.md (mesh path as given); bound None writes
    `normalize: false` (mesh and GCs in the decoder's frame, not normalised). frame: (center,
    scale) of the similarity x -> (x - center) * scale that took the decoder's frame to these
    GCs, recorded as `decoder_frame` so a condition on this file can map them back. body: the
    model's body frame {up, front} (`ngc_gen.data.body_frame`), recorded as `frame`."""
    d = {"name": name, "mesh": mesh,
         "normalize": False if bound is None else {"bound": float(bound)},
         "gcs": [rounded_gc_dict(g) for g in gcs]}
    if frame is not None:
        d["decoder_frame"] = {"center": [float(c) for c in frame[0]], "scale": float(frame[1])}
    if body is not None:
        d["frame"] = {"up": [float(x) for x in body["up"]],
                      "front": [float(x) for x in body["front"]], "source": "model"}
    return yaml.safe_dump(d, sort_keys=False, default_flow_style=None, width=100)


@dataclass
class WrittenShape:
    """A shape on disk: mesh and annotation paths, its codes and the GCs as written."""

    name: str
    mesh: Path
    annotation: Path
    codes: torch.Tensor
    gcs: list[dict]
    n_faces: int
    info: dict = field(default_factory=dict)
    bound: float | None = BOUND      # the YAML's normalize bound (None: normalize: false)
    body: dict | None = None         # the body frame {up, front} the YAML records


def write_shape(out_dir: Path, name: str, mesh: trimesh.Trimesh, gcs: list[dict],
                codes: torch.Tensor, info: dict | None = None,
                bound: float | None = BOUND, frame: tuple | None = None,
                body: dict | None = None) -> WrittenShape:
    """<out_dir>/<name>.ply and <name>.yaml (mesh: <name>.ply, normalize: {bound: 0.8}, or
    normalize: false for bound None; frame, body: `annotation_yaml`'s decoder and body
    frames)."""
    out_dir = Path(out_dir)
    ply, yml = out_dir / f"{name}.ply", out_dir / f"{name}.yaml"
    buf = io.BytesIO()
    mesh.export(buf, file_type="ply")
    atomic_write(ply, lambda f: f.write(buf.getvalue()))
    atomic_write_text(yml, annotation_yaml(name, ply.name, gcs, bound, frame, body))
    return WrittenShape(name, ply, yml, codes.detach().cpu().float(),
                        [rounded_gc_dict(g) for g in gcs], len(mesh.faces), dict(info or {}),
                        bound, body)


def write_edit_checkpoint(path: Path, ngc, shapes: list[WrittenShape], source: str = "") -> Path:
    """A `stage=fit`-format checkpoint (AutoDecoder, kind ngc) holding the NGC decoder and the
    shapes' codes, meta shapes {name, code_offset, n_codes, annotation_yaml (absolute mesh
    path)}: `edit.py run=<path> shape=<name>` and `load_autodecoder` take it unchanged."""
    import lightning as L

    from ngc_gen.lit.autodecoder import AutoDecoder

    metas, offset = [], 0
    for s in shapes:
        metas.append({"name": s.name, "code_offset": offset, "n_codes": len(s.codes),
                      "annotation_yaml": annotation_yaml(s.name, str(Path(s.mesh).resolve()),
                                                         s.gcs, s.bound, body=s.body)})
        offset += len(s.codes)
    module = AutoDecoder(kind="ngc", decoder=dict(ngc.config), n_codes=max(offset, 1), lr=0.0,
                         meta={"shapes": metas, "source": source})
    with torch.no_grad():
        module.decoder.load_state_dict(ngc.state_dict())
        if shapes:
            module.codes.weight.copy_(torch.cat([s.codes for s in shapes]))
    payload = {"hyper_parameters": dict(module.hparams), "state_dict": module.state_dict(),
               "pytorch-lightning_version": L.__version__, "global_step": 0, "epoch": 0}
    atomic_write(path, lambda f: torch.save(payload, f))
    return Path(path)
