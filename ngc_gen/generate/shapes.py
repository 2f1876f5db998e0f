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

from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.edit.blend import blend_features
from ngc_gen.extract import extract_mesh, per_gc_rows
from ngc_gen.extract.shapes import ngc_rows_fn, ngc_sdf_fn
from ngc_gen.geometry import GeneralizedCylinder

BOUND = 0.8


@dataclass
class DecodedShape:
    """name; latent (D,); gcs: GC dicts (template order, annotation format); codes (K, C)."""

    name: str
    latent: torch.Tensor
    gcs: list[dict]
    codes: torch.Tensor
    info: dict = field(default_factory=dict)


@torch.no_grad()
def decode_shapes(module, latents: torch.Tensor, names: list[str]) -> list[DecodedShape]:
    """Latents (B, D) through a ShapeLatentModule's shape decoder -> DecodedShapes."""
    latents = torch.as_tensor(latents, dtype=torch.float32)
    theta, codes = module.decode(latents)
    return [DecodedShape(n, s.detach().clone(), module.template.gc_dicts(t), c.detach().clone())
            for n, s, t, c in zip(names, latents, theta, codes)]


def gc_objects(gcs: list[dict]) -> list[GeneralizedCylinder]:
    return [GeneralizedCylinder.from_dict(d) for d in gcs]


def mixed_sdf_fn(ngc, codes_a: torch.Tensor, codes_b: torch.Tensor, part: int, weight):
    """sdf_fn(gc_index, rel) for `extract_mesh`: shape A's codes, except on GC `part` where the
    features are (1 - w(t)) g(f_A(t)) + w(t) g(f_B(t)) (paper Sec. 3.2 part mixing)."""
    plain = ngc_sdf_fn(ngc, codes_a)

    def fn(j: int, rel: torch.Tensor) -> torch.Tensor:
        if j != part:
            return plain(j, rel)
        u = rel[:, 0]
        fa = ngc.features(codes_a[j].expand(len(rel), -1), u)
        fb = ngc.features(codes_b[j].expand(len(rel), -1), u)
        t = ((u + 1.0) * 0.5).clamp(0.0, 1.0)
        return ngc.sdf_from_features(rel, blend_features(fa, fb, t, weight))
    return fn


def auto_chunk(resolution: int) -> int:
    """Network rows per call for a grid: extraction pads every call to `chunk` rows (bit-exact
    values whatever the batch), so keep it near the number of grid points a GC holds:
    resolution^3 / 128 within [2048, 65536] (16384 at 128^3)."""
    return int(min(65536, max(2048, int(resolution) ** 3 // 128)))


@torch.no_grad()
def extract_decoded(ngc, shape: DecodedShape, resolution: int = 128, bound: float = 1.0,
                    chunk: int | None = None, sdf_fn=None, progress: bool | None = False):
    """(mesh, stats) of a decoded shape at `resolution`^3 over [-bound, bound]^3, in the
    decoder's frame (not normalised). chunk None: `auto_chunk(resolution)`."""
    gcs = gc_objects(shape.gcs)
    rows_fn = per_gc_rows(sdf_fn) if sdf_fn is not None else ngc_rows_fn(ngc, shape.codes)
    res = extract_mesh(gcs, rows_fn, int(resolution), bound,
                       chunk=chunk or auto_chunk(resolution), progress=progress)
    return res.mesh, res.stats


def normalise(mesh: trimesh.Trimesh, gcs: list[dict], bound: float = BOUND):
    """Map mesh and GC dicts by x -> (x - center) * scale, the similarity that fits the mesh's
    bounding box into [-bound, bound]^3. An empty mesh is returned unchanged (scale 1)."""
    if len(mesh.vertices) == 0:
        return mesh, gcs, np.zeros(3), 1.0
    v = np.asarray(mesh.vertices, np.float64)
    lo, hi = v.min(0), v.max(0)
    center, scale = (lo + hi) / 2.0, float(bound) / (float((hi - lo).max()) / 2.0)
    out = trimesh.Trimesh((v - center) * scale, np.asarray(mesh.faces), process=False)
    return out, scale_gcs(gcs, center, scale), center, scale


def scale_gcs(gcs: list[dict], center, scale: float) -> list[dict]:
    """GC dicts under x -> (x - center) * scale (radii and caps scale; up and twist do not)."""
    c = np.asarray(center, np.float64)
    out = []
    for d in gcs:
        pts = (np.asarray(d["curve"]["points"], np.float64) - c) * scale
        out.append({**d, "curve": {**d["curve"], "points": pts.tolist()},
                    "keys": [{**k, "radii": [r * scale for r in k["radii"]]} for k in d["keys"]],
                    "caps": [x * scale for x in d["caps"]]})
    return out


def _rounded(gcs: list[dict]) -> list[dict]:
    """GC dicts with floats rounded to 7 decimals (readable YAML, still well below a voxel)."""
    r = lambda x: float(round(float(x), 7))  # noqa: E731
    return [{"name": d["name"],
             "curve": {"type": d["curve"]["type"],
                       "points": [[r(x) for x in p] for p in d["curve"]["points"]]},
             "up": [r(x) for x in d["up"]],
             "keys": [{"t": r(k["t"]), "radii": [r(x) for x in k["radii"]],
                       "twist": r(k.get("twist", 0.0))} for k in d["keys"]],
             "caps": [r(x) for x in d["caps"]]} for d in gcs]


def annotation_yaml(name: str, mesh: str, gcs: list[dict], bound: float = BOUND) -> str:
    """Annotation YAML of DESIGN.md section 2 (mesh path as given)."""
    d = {"name": name, "mesh": mesh, "normalize": {"bound": float(bound)}, "gcs": _rounded(gcs)}
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


def write_shape(out_dir: Path, name: str, mesh: trimesh.Trimesh, gcs: list[dict],
                codes: torch.Tensor, info: dict | None = None) -> WrittenShape:
    """<out_dir>/<name>.ply and <name>.yaml (mesh: <name>.ply, normalize: {bound: 0.8})."""
    out_dir = Path(out_dir)
    ply, yml = out_dir / f"{name}.ply", out_dir / f"{name}.yaml"
    buf = io.BytesIO()
    mesh.export(buf, file_type="ply")
    atomic_write(ply, lambda f: f.write(buf.getvalue()))
    atomic_write_text(yml, annotation_yaml(name, ply.name, gcs))
    return WrittenShape(name, ply, yml, codes.detach().cpu().float(), _rounded(gcs),
                        len(mesh.faces), dict(info or {}))


def write_edit_checkpoint(path: Path, ngc, shapes: list[WrittenShape], source: str = "") -> Path:
    """A `stage=fit`-format checkpoint (AutoDecoder, kind ngc) holding the NGC decoder and the
    shapes' codes, meta shapes {name, code_offset, n_codes, annotation_yaml (absolute mesh
    path)}: `edit.py ckpt=<path> shape=<name>` and `load_autodecoder` take it unchanged."""
    import lightning as L

    from ngc_gen.lit.autodecoder import AutoDecoder

    metas, offset = [], 0
    for s in shapes:
        metas.append({"name": s.name, "code_offset": offset, "n_codes": len(s.codes),
                      "annotation_yaml": annotation_yaml(s.name, str(Path(s.mesh).resolve()),
                                                         s.gcs)})
        offset += len(s.codes)
    module = AutoDecoder(kind="ngc", decoder=dict(ngc.config), n_codes=max(offset, 1),
                         meta={"shapes": metas, "source": source})
    with torch.no_grad():
        module.decoder.load_state_dict(ngc.state_dict())
        if shapes:
            module.codes.weight.copy_(torch.cat([s.codes for s in shapes]))
    payload = {"hyper_parameters": dict(module.hparams), "state_dict": module.state_dict(),
               "pytorch-lightning_version": L.__version__, "global_step": 0, "epoch": 0}
    atomic_write(path, lambda f: torch.save(payload, f))
    return Path(path)
