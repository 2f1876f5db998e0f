"""What every sample.py mode writes: each shape's mesh and GC annotation, then latents.pt,
shapes.ckpt (for `edit.py run=<out_dir>`) and summary.json; shared by generate, interpolate,
mix (`sample`) and condition (`condition`)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError
from ngc_gen.generate.model import ShapeGenerator
from ngc_gen.generate.shapes import (BOUND, WrittenShape, auto_chunk, normalise,
                                     write_edit_checkpoint, write_shape)
from ngc_gen.shape import Shape

LATENTS_KIND = "ngc_gen.generated_latents"


def _check(ok: bool, what: str, field: str, fix: str) -> None:
    if not ok:
        raise DataError(what, field=field, fix=fix)


def extract_and_write(gen: ShapeGenerator, shapes: list[Shape], out_dir: Path,
                      resolution: int = 128, bound: float = 1.0, chunk: int | None = None,
                      normalised: bool = True, progress: bool = True,
                      settings=None) -> tuple[list[WrittenShape], list[float]]:
    """Extract each shape's mesh (settings: the sparse refinement, `SparseSettings`; None: the
    library's) and write its PLY + YAML. Returns the written shapes and the seconds per mesh."""
    written, seconds = [], []
    for shape in tqdm(shapes, desc="meshes", unit="shape", disable=not progress or len(shapes) < 2):
        t0 = time.perf_counter()
        mesh = shape.mesh(resolution, bound, chunk=chunk or auto_chunk(resolution),
                          settings=settings, progress=False).mesh
        gcs = shape.gc_dicts()
        center, scale = np.zeros(3), 1.0
        if normalised:
            mesh, gcs, center, scale = normalise(mesh, gcs)
        seconds.append(time.perf_counter() - t0)
        info = {**{k: v for k, v in shape.info.items() if k != "latent"}, "n_faces": len(mesh.faces), "watertight": bool(mesh.is_watertight),
                "normalise_center": np.asarray(center).tolist(), "normalise_scale": scale,
                "extract_s": seconds[-1]}
        if len(mesh.faces) == 0:
            tqdm.write(f"warning: {shape.name}: the decoded SDF has no zero level set inside its "
                       f"GCs (empty mesh)")
        written.append(write_shape(out_dir, shape.name, mesh, gcs, shape.codes, info,
                                   BOUND if normalised else None,
                                   (center, scale) if normalised else None, gen.frame))
    return written, seconds


def write_outputs(gen: ShapeGenerator, out_dir: Path, mode: str, written: list[WrittenShape],
                  latents: torch.Tensor, names: list[str], summary: dict,
                  edit_shapes: list[WrittenShape] | None = None) -> dict:
    """latents.pt, shapes.ckpt and summary.json; prints where things are."""
    payload = {"kind": LATENTS_KIND, "mode": mode, "names": list(names),
               "latents": latents.detach().cpu().float().clone(), "source": gen.source,
               **{k: v for k, v in summary.items() if k in ("seed", "alphas", "a", "b")}}
    atomic_write(workspace.latents(out_dir), lambda f: torch.save(payload, f))
    edit = edit_shapes if edit_shapes is not None else written
    ckpt = write_edit_checkpoint(workspace.shapes_checkpoint(out_dir), gen.ngc, edit,
                                 source=f"sample.py mode={mode} run={gen.source}")
    summary = {"mode": mode, "source": gen.source, "out_dir": str(out_dir), "frame": gen.frame,
               "edit_checkpoint": str(ckpt), "edit_shapes": [s.name for s in edit], **summary,
               "shapes": {s.name: {"mesh": str(s.mesh), "annotation": str(s.annotation), **s.info}
                          for s in written}}
    atomic_write_text(workspace.summary(out_dir), json.dumps(summary, indent=2))
    print(f"\n{len(written)} shapes in {out_dir}: <name>.ply + <name>.yaml, latents.pt, "
          f"shapes.ckpt, summary.json")
    for s in written:
        print(f"  {s.name:20s} {s.n_faces:7d} faces   {s.annotation.name}")
    if edit:
        print(f"edit one: python edit.py run={out_dir} shape={edit[0].name} edit=<program>")
    return summary
