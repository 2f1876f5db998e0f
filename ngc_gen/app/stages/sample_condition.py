"""What `sample.py mode=condition gcs=<yaml>` does: n shapes whose GCs match the given ones.

Writes, like the other modes, per shape `<name>.ply` + `<name>.yaml`, `latents.pt`,
`shapes.ckpt` and `summary.json`, plus `condition.yaml` (the GCs conditioned on, as read) and
the picture `shapes.png` (the drawn GCs, then the shapes with their GCs). Shapes stay in the
frame of the given GCs (`normalize: false` in their YAML): what the user drew is where they
get it, verbatim with `replace: true`.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import yaml

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write_text

from ngc_gen.generate.condition import (conditional_latents, gc_error, load_condition,
                                        with_given_gcs)
from ngc_gen.generate.model import ShapeGenerator
from ngc_gen.generate.shapes import decode_shapes
from ngc_gen.geometry import GeneralizedCylinder

from ..runtime.outputs import _check, extract_and_write, write_outputs


def condition(gen: ShapeGenerator, out_dir, gcs, n: int, seed: int, strength: float,
              project_steps: int, replace: bool, resolution: int = 128, bound: float = 1.0,
              chunk: int | None = None, sampler: dict | None = None,
              progress: bool = True, settings=None) -> dict:
    """n shapes conditioned on the GCs in YAML file `gcs` (shape i from latent_seed(seed, i),
    as mode=generate); see ngc_gen.generate.condition for strength and project_steps."""
    _check(int(n) >= 1, f"n must be >= 1, got {n}", "n", "ask for at least one shape")
    _check(gcs not in (None, ""), "no condition given", "gcs",
           "pass gcs=<YAML with the GCs to keep> (an annotation, sample.py's or edit.py's)")
    gen._need_diffusion("conditional sampling")
    cond = load_condition(gcs, gen.shape_latent.template)
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    latents = conditional_latents(gen, cond, range(int(n)), seed, strength, project_steps,
                                  sampler)
    latent_s = (time.perf_counter() - t0) / int(n)
    err = gc_error(gen.shape_latent.shape_decoder, latents, cond)
    names = [f"cond_{i:03d}" for i in range(int(n))]
    shapes = decode_shapes(gen.shape_latent, latents, names)
    for i, (s, e) in enumerate(zip(shapes, err.tolist())):
        s.info["gc_err_std"] = e
        if replace:
            shapes[i] = with_given_gcs(s, cond)
    written, secs = extract_and_write(gen, shapes, out_dir, resolution, bound, chunk,
                                      normalised=False, progress=progress, settings=settings)
    atomic_write_text(workspace.condition(out_dir), yaml.safe_dump(
        {"name": "condition", "source": cond.source, "gcs": list(cond.gcs)}, sort_keys=False,
        default_flow_style=None, width=100))
    summary = {"n": int(n), "seed": int(seed), "condition": cond.source,
               "condition_gcs": list(cond.names), "strength": float(strength),
               "project_steps": int(project_steps), "replace": bool(replace),
               "gc_err_std": err.tolist(), "resolution": int(resolution),
               "sampler": dict(sampler or {}), "latent_s_per_shape": latent_s,
               "mesh_s_per_shape": float(np.mean(secs))}
    summary = write_outputs(gen, out_dir, "condition", written, latents, names, summary)
    print(f"conditioned on {len(cond)} GCs ({', '.join(cond.names)}) from {cond.source}: "
          f"decoded GC error {float(err.mean()):.3f} std (mean; before replace), "
          f"{'GCs replaced by the given ones' if replace else 'decoded GCs kept'}; "
          f"latent {1e3 * latent_s:.0f} ms per shape")
    return summary


def render_condition(summary: dict, path: Path, per_row: int = 4, limit: int = 8,
                     up="auto"):
    """The given GCs (left) and up to `limit` conditioned shapes with their GCs translucent, in
    rows of `per_row`, at one scale per row; `up`: `viz.up`. None if nothing could be drawn."""
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.viz import gcs_surface, render_grid, render_or_warn

    shown = [(n, s) for n, s in summary["shapes"].items() if s.get("n_faces", 0) > 0][:limit]
    if not shown:
        return None
    cond = yaml.safe_load(workspace.condition(summary["out_dir"]).read_text())
    drawn = gcs_surface([GeneralizedCylinder.from_dict(d) for d in cond["gcs"]])
    cells = [(trimesh.load(s["mesh"], process=False),
              gcs_surface(load_annotation(s["annotation"]).gcs)) for _, s in shown]
    labels = [f"{n} ({s['gc_err_std']:.2f} std)" for n, s in shown]
    rows = [[drawn] + cells[i:i + per_row] for i in range(0, len(cells), per_row)]
    titles = [["given GCs"] + labels[i:i + per_row] for i in range(0, len(cells), per_row)]
    return render_or_warn(render_grid, path, rows, titles=titles, frame="row",
                          up=up)
