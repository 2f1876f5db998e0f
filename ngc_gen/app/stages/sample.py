"""What `sample.py` does (its runner): generate N shapes, interpolate between two, mix a part
of one into another. Every mode writes, into its output directory, per shape `<name>.ply` +
`<name>.yaml` (the GC annotation, editable), `latents.pt` ({names, latents (S, D), ...}),
`shapes.ckpt` (a fit-format checkpoint of the shapes' codes and the NGC decoder, for
`edit.py run=<out_dir>`) and `summary.json` (settings and timings); `sample.py` adds
`shapes.png` (picture=true)."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from ngc_gen import workspace
from ngc_gen.data.errors import DataError
from ngc_gen.edit import BLEND_PARAMS, EditError, mix_weight
from ngc_gen.generate.latents import latent_path
from ngc_gen.generate.model import ShapeGenerator
from ngc_gen.generate.shapes import decode_shapes
from ngc_gen.viz.camera import frame_up

from ..runtime.checks import check_sample
from ..runtime.config import sparse_settings
from ..runtime.outputs import _check, extract_and_write, write_outputs
from .settings import mode_settings


def generate(gen: ShapeGenerator, out_dir, n: int = 16, seed: int = 0, resolution: int = 128,
             bound: float = 1.0, chunk: int | None = None, sampler: dict | None = None,
             normalised: bool = True, progress: bool = True, settings=None) -> dict:
    """n new shapes: EDM latents (shape i from latent_seed(seed, i)) decoded to GCs + codes."""
    _check(int(n) >= 1, f"n must be >= 1, got {n}", "n", "ask for at least one shape")
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    latents = gen.sample_latents(range(int(n)), seed, **(sampler or {}))
    latent_s = (time.perf_counter() - t0) / int(n)
    names = [f"sample_{i:03d}" for i in range(int(n))]
    shapes = decode_shapes(gen.shape_latent, latents, names)
    written, secs = extract_and_write(gen, shapes, out_dir, resolution, bound, chunk, normalised,
                                      progress=progress, settings=settings)
    summary = {"n": int(n), "seed": int(seed), "resolution": int(resolution),
               "sampler": dict(sampler or {}), "latent_s_per_shape": latent_s,
               "mesh_s_per_shape": float(np.mean(secs))}
    summary = write_outputs(gen, out_dir, "generate", written, latents, names, summary)
    print(f"time per shape: latent {1e3 * latent_s:.1f} ms, mesh at {resolution}^3 "
          f"{np.mean(secs):.2f} s")
    return summary


def interpolate(gen: ShapeGenerator, out_dir, a=0, b=1, steps: int = 8, seed: int = 0,
                method: str = "lerp", resolution: int = 128, bound: float = 1.0,
                chunk: int | None = None, sampler: dict | None = None, normalised: bool = True,
                progress: bool = True, settings=None) -> dict:
    """`steps` shapes along the latent path from a to b (alpha = 0 .. 1, both ends included).
    a, b: training shape names or generated indices. method: lerp, or slerp about the mean of
    the training latents."""
    _check(int(steps) >= 2, f"steps must be >= 2, got {steps}", "steps",
           "ask for at least the two end shapes")
    _check(method in ("lerp", "slerp"), f"unknown interpolation {method!r}", "interp",
           "use interp=lerp or interp=slerp")
    out_dir = Path(out_dir)
    name_a, za = gen.resolve(a, seed, **(sampler or {}))
    name_b, zb = gen.resolve(b, seed, **(sampler or {}))
    alphas, latents = latent_path(za, zb, int(steps), method, gen.train_latents.double().mean(0))
    names = [f"interp_{k:02d}" for k in range(int(steps))]
    shapes = decode_shapes(gen.shape_latent, latents, names)
    for s, al in zip(shapes, alphas.tolist()):
        s.info["alpha"] = al
    written, secs = extract_and_write(gen, shapes, out_dir, resolution, bound, chunk, normalised,
                                      progress=progress, settings=settings)
    summary = {"a": name_a, "b": name_b, "seed": int(seed), "method": method,
               "alphas": alphas.tolist(), "resolution": int(resolution),
               "mesh_s_per_shape": float(np.mean(secs))}
    return write_outputs(gen, out_dir, "interpolate", written, latents, names, summary)


def mix(gen: ShapeGenerator, out_dir, a=0, b=1, part: str = "head", blend: str = "replace",
        blend_params: dict | None = None, geometry: str = "source", seed: int = 0,
        resolution: int = 128, bound: float = 1.0, chunk: int | None = None,
        sampler: dict | None = None, normalised: bool = True, progress: bool = True,
        settings=None) -> dict:
    """Shape A with part `part` of shape B (`Shape.with_part`, the edit op `mix`'s rule):
    geometry="source" (default) takes B's GC for the part, attached at A's joint, and B's
    features; "target" keeps A's GC and blends features by the weight (blend + blend_params).
    Writes A, B and `mix_<part>`.

    The mixed shape's field blends features, not codes: it is written as mesh + YAML, and
    shapes.ckpt holds A and B (edit those; the mix is recorded in summary.json)."""
    out_dir = Path(out_dir)
    gen.shape_latent.template.index(str(part))  # DataError naming the template's GCs
    try:
        weight = mix_weight(str(blend), **(blend_params or {}))
    except EditError as e:
        raise DataError(str(e), field="blend",
                        fix="blend=replace, blend=truncated_linear t0=.. t1=.., blend=smoothstep "
                            "t0=.. t1=.., blend=linear or blend=constant w=..") from None
    _check(geometry in ("source", "target"), f"unknown geometry {geometry!r}", "geometry",
           "use geometry=source (B's part at A's joint) or geometry=target (A's GC)")
    name_a, za = gen.resolve(a, seed, **(sampler or {}))
    name_b, zb = gen.resolve(b, seed, **(sampler or {}))
    _check(name_a != name_b, f"a and b are the same shape ({name_a})", "a/b",
           "mix two different shapes")
    sa, sb = decode_shapes(gen.shape_latent, torch.stack([za, zb]), [name_a, name_b])
    mixed = sa.with_part(str(part), sb, weight=weight, geometry=geometry).replaced(
        name=f"mix_{part}", info={"a": name_a, "b": name_b, "part": str(part),
                                  "blend": repr(weight) if weight else "replace",
                                  "geometry": geometry})
    written, secs = extract_and_write(gen, [sa, sb, mixed], out_dir, resolution, bound, chunk,
                                      normalised, progress=progress, settings=settings)
    summary = {"a": name_a, "b": name_b, "part": str(part), "geometry": geometry,
               "blend": repr(weight) if weight else "replace",
               "seed": int(seed), "resolution": int(resolution),
               "mesh_s_per_shape": float(np.mean(secs))}
    return write_outputs(gen, out_dir, "mix", written, torch.stack([za, zb]), [name_a, name_b],
                         summary, edit_shapes=written[:2])


def _generate(gen, out_dir, s, common: dict) -> dict:
    return generate(gen, out_dir, n=s.n, **common)


def _interpolate(gen, out_dir, s, common: dict) -> dict:
    return interpolate(gen, out_dir, a=s.a, b=s.b, steps=s.steps, method=s.interp, **common)


def _mix(gen, out_dir, s, common: dict) -> dict:
    params = {k: getattr(s, k) for k in BLEND_PARAMS.get(s.blend, ())
              if getattr(s, k, None) is not None}
    return mix(gen, out_dir, a=s.a, b=s.b, part=s.part, blend=s.blend, blend_params=params,
               geometry=s.geometry, **common)


def _condition(gen, out_dir, s, common: dict) -> dict:
    from .sample_condition import condition

    kw = {k: v for k, v in common.items() if k != "normalised"}  # the given GCs' frame
    return condition(gen, out_dir, gcs=s.gcs, n=s.n, **s.condition, **kw)


# mode -> how it runs on its settings (`settings.MODES`) and the settings every mode shares
MODE_RUNNERS = {"generate": _generate, "interpolate": _interpolate, "mix": _mix,
                "condition": _condition}


def run_sample(cfg) -> dict:
    """Dispatch `sample.py` (conf/sample.yaml) to a mode."""
    from omegaconf import OmegaConf

    from ngc_gen.generate.model import load_generator

    if cfg.get("mode") == "export":  # a shape of any run as a rigged GLB (checks its input)
        from .export_shape import run_export
        return run_export(cfg)
    check_sample(cfg)  # again for callers other than sample.py (the pipeline, tests); cheap
    c = OmegaConf.to_container(cfg, resolve=True)
    mode = c["mode"]
    ex = c["extract"]
    gen = load_generator(c["run"], c.get("shape_latent_run"))
    if c.get("latents"):
        gen.add_latents(c["latents"])
    common = dict(seed=int(c["seed"]), resolution=int(ex["resolution"]), bound=float(ex["bound"]),
                  chunk=None if ex["chunk"] is None else int(ex["chunk"]), sampler=c["sampler"],
                  normalised=bool(c["normalise"]), progress=bool(c["progress"]),
                  settings=sparse_settings(cfg.extract.sparse))
    out_dir = Path(c["out_dir"])
    summary = MODE_RUNNERS[mode](gen, out_dir, mode_settings(cfg), common)
    up = frame_up(c["viz"]["up"], gen.frame)  # upright in the collection's body frame
    if c.get("picture", True) and mode == "condition":
        from .sample_condition import render_condition
        picture = render_condition(summary, workspace.picture(out_dir, "sample"), up=up)
        if picture is not None:
            print(f"picture: {picture}")
    elif c.get("picture", True):
        picture = render_shapes(summary, workspace.picture(out_dir, "sample"),
                                one_row=mode != "generate", up=up)
        if picture is not None:
            print(f"picture: {picture}")
    return summary


def render_shapes(summary: dict, path: Path, one_row: bool = False, limit: int = 32,
                  up="auto"):
    """A picture of the written shapes (at most `limit`), each with its GCs drawn translucent:
    what was made, and the handles edit.py will move. `up`: `viz.up`. None if nothing could
    be drawn."""
    import trimesh

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.viz import gcs_surface, render_gallery, render_or_warn

    shown = [(n, s) for n, s in summary["shapes"].items() if s.get("n_faces", 0) > 0][:limit]
    if not shown:
        return None
    cells = [(trimesh.load(s["mesh"], process=False),
              gcs_surface(load_annotation(s["annotation"]).gcs)) for _, s in shown]
    per_row = len(cells) if one_row and len(cells) <= 8 else 4
    return render_or_warn(render_gallery, path, cells, [n for n, _ in shown], per_row=per_row,
                          up=up)
