"""`edit.py`: apply an edit program to a shape of a fitted checkpoint and write the results.

Everything that can fail on bad input (the program's structure, the checkpoint, the shape, GC
names and every op's values, mix sources) is checked before the first file is written; the
outputs are then written atomically into the output folder:

    undeformed.ply   the NGC mesh of the shape as fitted (same resolution and union)
    deformed.ply     the NGC mesh after the program (edited GCs, mixed features)
    edited.yaml      annotation with the edited GCs (ngc_gen.data.load_annotation reads it;
                     its mesh is deformed.ply)
    program.yaml     the program as run (shape filled in)
    metrics.json     eps_v, eps_a (deformed vs undeformed), volumes, areas, timings, op log
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import yaml

# light imports only: the program and out_dir are checked before torch loads (`run_edit`)
from ngc_gen import workspace
from ngc_gen.edit.errors import EditError

from ..runtime.background_render import BackgroundRenderer
from ..runtime.checkpoints import fit_checkpoint
from ..runtime.checks import check_edit, edit_output_dir
from ..runtime.config import sparse_settings
from ..runtime.mix_sources import MixSources
from ..runtime.programs import program_from_config

# edit.png's cell (pixels): large enough that a moved limb shows (3 cells side by side)
EDIT_CELL = (560, 440)

def _json_safe(x):
    import numpy as np

    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return x


def _mesh_stats(mesh, prefix: str) -> dict:
    empty = len(mesh.faces) == 0
    return {f"volume_{prefix}": None if empty else float(mesh.volume),
            f"area_{prefix}": float(mesh.area), f"watertight_{prefix}": bool(mesh.is_watertight),
            f"n_faces_{prefix}": int(len(mesh.faces))}


def run_edit(cfg) -> dict:
    """Validate and apply the program, extract both meshes, then write every output. The
    program's structure and the output folder are checked first, before torch loads."""
    if cfg.get("viewer"):  # the interactive editor (conf/editor)
        from ngc_gen.app.editor.server import serve

        return serve(cfg)
    t_start = time.perf_counter()
    check_edit(cfg)  # again for callers other than edit.py (the pipeline, tests); cheap
    parts = program_from_config(cfg)
    out_dir = edit_output_dir(cfg, parts["name"])
    # the picture's renderer warms up in a child while the model loads and is meshed here
    with BackgroundRenderer(enabled=bool(cfg.get("picture", True))) as renderer:
        return _apply(cfg, parts, out_dir, renderer, t_start)


def _apply(cfg, parts: dict, out_dir: Path, renderer, t_start: float) -> dict:
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.data.errors import DataError
    from ngc_gen.edit.crossings import crossing_warning
    from ngc_gen.edit.program import EditProgram
    from ngc_gen.lit.checkpoint import load_autodecoder
    from ngc_gen.shape import shapes_from_autodecoder
    from ngc_gen.viz.camera import frame_up

    program = EditProgram(**parts)
    ckpt = fit_checkpoint(cfg.get("run"))
    module = load_autodecoder(ckpt)
    if module.hparams.kind != "ngc":
        raise DataError(f"{ckpt} holds a {module.hparams.kind} model; edits need NGC GCs",
                        fix="pass a run fitted with model=small or model=paper")
    shapes = shapes_from_autodecoder(module)
    names = list(shapes)
    shape = cfg.get("shape") or program.shape
    if shape is None or shape not in names:
        raise EditError(("the program names no shape" if shape is None else
                         "unknown shape") + f"; the checkpoint holds {names}",
                        program=program.source, field="shape", value=shape,
                        fix="pass shape=<name> on the command line")
    original = shapes[shape]
    gcs = original.gcs

    t0 = time.perf_counter()
    edited = original.edited(program, MixSources(shapes, original, checkpoint=ckpt))
    t_edit = time.perf_counter() - t0
    log = edited.info["edit_log"]
    warning = crossing_warning(edited.info.get("crossings", {}))
    if warning:
        print(f"warning: {warning}", flush=True)
    mixes = {original.gc_names[j]: m.label for j, m in edited.mixes.items()}

    ex = cfg.extract
    kw = dict(resolution=int(ex.resolution), bound=float(ex.bound), chunk=int(ex.chunk),
              settings=sparse_settings(ex.sparse))
    t0 = time.perf_counter()
    before = original.replaced(smooth=edited.smooth).mesh(**kw)
    t_before = time.perf_counter() - t0
    t0 = time.perf_counter()
    after = edited.mesh(**kw)
    t_after = time.perf_counter() - t0

    metrics = {"program": program.name, "program_file": program.source, "shape": shape,
               "checkpoint": str(ckpt), "resolution": int(ex.resolution),
               "smooth_union": program.smooth_union}
    # the runner is a stage in all but location: it reads the (higher) eval layer's metric
    from ngc_gen.eval import volume_area_change

    try:
        metrics.update(volume_area_change(before.mesh, after.mesh))
    except ValueError:
        metrics.update(eps_v=None, eps_a=None)
    metrics.update(_mesh_stats(before.mesh, "before"), **_mesh_stats(after.mesh, "after"))
    metrics.update(time_edit_s=t_edit, time_extract_before_s=t_before,
                   time_extract_after_s=t_after, ops=log, mixes=mixes,
                   crossings=edited.info.get("crossings", {}),
                   convention="eps_v = |V'-V|/V, eps_a = |A'-A|/A (fractions) of the deformed "
                              "vs the undeformed NGC mesh, marching cubes at the same "
                              "resolution; V from trimesh (watertight meshes)")

    _write_outputs(cfg, out_dir, shape, program, before.mesh, after.mesh, gcs, edited.gcs,
                   metrics, renderer, original.info.get("frame"))
    metrics["time_total_s"] = time.perf_counter() - t_start
    metrics["out_dir"] = str(out_dir)
    atomic_write_text(workspace.metrics(out_dir), json.dumps(_json_safe(metrics), indent=2))
    print_summary(metrics)
    return metrics


def _write_outputs(cfg, out_dir: Path, shape: str, program, before, after, gcs, edited_gcs,
                   metrics: dict, renderer, frame: dict | None = None) -> None:
    """The edit's files (nothing before wrote one): both meshes, edited.yaml, program.yaml and
    the picture (its path into `metrics`). before, after: the meshes; gcs, edited_gcs: the GCs;
    frame: the shape's body frame (edited.yaml keeps it; the picture stands on it)."""
    from ngc_gen.data.annotations import Annotation
    from ngc_gen.data.atomic import atomic_write, atomic_write_text
    from ngc_gen.data.body_frame import read_frame
    from ngc_gen.viz.camera import frame_up

    # GCs and mesh share the fitted NGC frame: `normalize: false` keeps it, so the file can be
    # prepared and fitted again as it is (an AnnotatedShapes list, docs/editing.md)
    edited = Annotation(name=f"{shape}_{program.name}", mesh=str(out_dir / workspace.DEFORMED),
                        gcs=edited_gcs, bound=None, frame=read_frame(frame))
    header = (f"# GCs of '{shape}' after edit program '{program.name}' ({program.source}), in "
              f"the fitted NGC frame (normalize: false).\n# mesh: the deformed NGC mesh"
              + (f"; mixed parts (features, not stored here): {metrics['mixes']}"
                 if metrics['mixes'] else "") + "\n")
    for name, mesh in ((workspace.UNDEFORMED, before), (workspace.DEFORMED, after)):
        atomic_write(out_dir / name, lambda f, m=mesh: f.write(m.export(file_type="ply")))
    atomic_write_text(workspace.edited(out_dir), header + edited.to_yaml(relative_to=out_dir))
    prog = {"name": program.name, "description": program.description, "shape": shape,
            "smooth_union": program.smooth_union, "ops": program.ops}
    atomic_write_text(out_dir / workspace.PROGRAM,
                      yaml.safe_dump(_json_safe(prog), sort_keys=False, default_flow_style=None,
                                     width=100))
    if cfg.get("picture", True):
        metrics["picture"] = render_edit(before, gcs, after, edited_gcs,
                                         workspace.picture(out_dir, "edit"), program.name,
                                         up=frame_up(cfg.viz.up, frame), renderer=renderer)


def render_edit(before, gcs, after, edited_gcs, path: Path, program: str,
                up="auto", renderer=None, cell=EDIT_CELL) -> str | None:
    """edit.png: the shape before and after (bare, so no GC shell hides the moved part), then
    the GCs after the edit (solid) over the GCs before (translucent); one camera for all three,
    looking across the edited GCs' motion (`viz.camera.edit_view`); `up`: `viz.up` (or the
    shape's body frame, `viz.camera.frame_up`). `renderer`: a `BackgroundRenderer` to draw in
    (None: draw here)."""
    import numpy as np

    from ngc_gen.viz import gcs_surface, render_grid, render_or_warn
    from ngc_gen.viz.camera import edit_view, resolve_up

    shells = gcs_surface(gcs), gcs_surface(edited_gcs)
    u = resolve_up(up, [before])
    view = edit_view(np.concatenate([np.asarray(m.vertices) for m in (before, after, *shells)]),
                     gcs, edited_gcs, u)
    draw = render_or_warn if renderer is None else renderer.render
    done = draw(render_grid, path, [[before, after, (shells[1], shells[0])]],
                col_titles=["before", f"after {program}", "GCs after (solid), before"],
                frame="row", view=view, up=u, cell=cell)
    return None if done is None else str(done)


def print_summary(m: dict) -> None:
    pct = lambda x: "n/a" if x is None else f"{100 * x:.2f}%"  # noqa: E731
    print(f"edit '{m['program']}' on shape '{m['shape']}' ({len(m['ops'])} ops, "
          f"{m['time_edit_s'] * 1e3:.0f} ms)")
    for rec in m["ops"]:
        extra = "".join(f", {k} {rec[k]}" for k in ("carried", "followers", "sources")
                        if rec.get(k))
        print(f"  {rec['op']:10s} {', '.join(rec['gcs'])}{extra}")
    print(f"volume change eps_v {pct(m['eps_v'])}, area change eps_a {pct(m['eps_a'])} "
          f"(deformed vs undeformed NGC mesh, resolution {m['resolution']})")
    print(f"extraction {m['time_extract_before_s']:.1f} s + {m['time_extract_after_s']:.1f} s; "
          f"outputs in {m['out_dir']}")
