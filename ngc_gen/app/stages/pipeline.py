"""Stage `pipeline`: the whole job, step after step, in one command.

    python train.py experiment=demo    # `make demo`: fit, edit, shape_latent, diffusion, sample
    python train.py experiment=collection data.path=DIR annotate.template=T   # your meshes:
        # annotate, shape_latent, diffusion, sample, interpolate (stages/collection.py)

Each step is an ordinary run of `train.py`, `edit.py` or `sample.py`, composed from its own
config with the overrides listed under `pipeline.<step>` (what you would type after that
command) and written to `<run>/<step>/`, exactly as the single command would write it. A step
that reads an earlier one gets the link filled in (edit: `run=<run>/fit`,
diffusion: `shape_latent_run=<run>/shape_latent`, sample and interpolate: `run=<run>/diffusion`,
shape_latent after annotate: `data.path=<run>/annotate`) unless its overrides set it; an
interpolation without `a` and `b` runs between two training shapes (the first and the one
farthest from it). Every step's config is composed
before the first one runs, so a typo fails in seconds, not after the fit. At the end the run
directory holds `summary.json` (per step: directory, seconds, headline numbers) and
`overview.png` (fitted, edited and generated shapes). After a failure, rerun with
`pipeline.resume=true hydra.run.dir=<that run>` to keep the steps that finished.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.errors import DataError

from ..runtime.next_hint import overrides_used
from .collection import check_annotated, interpolation_pair
from .registry import COMMANDS, run_stage


# step -> (config name, the key that holds its output directory)
STEPS = {"annotate": ("train", "run_dir"), "fit": ("train", "run_dir"),
         "edit": ("edit", "out_dir"), "shape_latent": ("train", "run_dir"),
         "diffusion": ("train", "run_dir"), "sample": ("sample", "out_dir"),
         "interpolate": ("sample", "out_dir")}
# step -> (the step it reads, the override that points at it)
LINKS = {"edit": ("fit", "run={}"),
         "diffusion": ("shape_latent", "shape_latent_run={}"),
         "sample": ("diffusion", "run={}"),
         "interpolate": ("diffusion", "run={}")}
# links taken only when the step they read runs before (else the step reads its own data)
OPTIONAL_LINKS = {"shape_latent": ("annotate", "data.path={}")}


# the pipeline's steps that are commands (edit.py, sample.py), not train.py stages
STEP_COMMANDS = {"edit": "edit", "sample": "sample", "interpolate": "sample"}


def _fail(what: str, step: str | None = None, fix: str = "") -> DataError:
    return DataError(what, field=f"pipeline.{step}" if step else "pipeline", fix=fix)


def plan(cfg: DictConfig, run_dir: Path) -> list[tuple[str, DictConfig]]:
    """[(step, composed config)] in run order; DataError for an unknown step, a missing link or
    an override Hydra rejects, before anything runs."""
    return [(step, composed) for step, composed, _ in planned_steps(cfg, run_dir)]


def planned_steps(cfg: DictConfig, run_dir: Path) -> list[tuple[str, DictConfig, list[str]]]:
    """`plan`'s steps with the overrides each was composed from (its `next:` hint repeats
    them)."""
    from ..runtime.config import compose_config

    p = cfg.get("pipeline")
    if not p or not p.get("steps"):
        raise _fail("no pipeline steps", fix="use experiment=demo, or set pipeline.steps=[...] "
                    "with each step's overrides under pipeline.<step>")
    order = list(p.steps)
    out = []
    for i, step in enumerate(order):
        if step not in STEPS:
            raise _fail(f"unknown step {step!r}", fix=f"steps are {', '.join(STEPS)}")
        if step in order[:i]:
            raise _fail(f"step {step!r} is listed twice", fix="list each step once")
        config_name, out_key = STEPS[step]
        spec = OmegaConf.to_container(p.get(step) or [], resolve=True)
        if not isinstance(spec, list) or not all(isinstance(o, str) and "=" in o for o in spec):
            raise _fail(f"pipeline.{step} must be a list of overrides, got {spec!r}", step,
                        fix="write e.g. [data=creatures, trainer.max_steps=100]; on the command "
                            "line quote each: 'pipeline.fit=[\"data=ant\"]'")
        overrides = list(spec)
        keys = {o.split("=", 1)[0].lstrip("+~") for o in overrides}
        if step in LINKS and LINKS[step][1].split("=", 1)[0] not in keys:
            source, template = LINKS[step]
            if source not in order[:i]:
                raise _fail(f"step {step!r} reads step {source!r}, which does not run before it",
                            step, fix=f"run {source!r} first, or give {template.format('<dir>')} "
                                      f"in pipeline.{step}")
            overrides.append(template.format(run_dir / source))
        if step in OPTIONAL_LINKS and OPTIONAL_LINKS[step][0] in order[:i] \
                and OPTIONAL_LINKS[step][1].split("=", 1)[0] not in keys:
            overrides.append(OPTIONAL_LINKS[step][1].format(run_dir / OPTIONAL_LINKS[step][0]))
        overrides.append(f"{out_key}={run_dir / step}")
        if step not in STEP_COMMANDS:
            overrides.append(f"stage={step}")
        try:
            composed = compose_config(config_name, overrides)
        except Exception as e:  # Hydra's override / missing-config errors
            raise _fail(f"step {step!r}: {e}", step,
                        fix=f"check the overrides in pipeline.{step}: {overrides}") from e
        trainer = composed.get("trainer") or {}
        if str(trainer.get("strategy", "")).startswith("ddp") or trainer.get("devices", 1) != 1:
            # ranks > 0 rerun the whole command: they would run the pipeline's other steps too
            raise _fail(f"step {step!r} asks for several processes ({trainer.get('strategy')}, "
                        f"devices {trainer.get('devices')})", step,
                        fix=f"run it as its own command: python train.py stage={step} "
                            f"trainer=ddp ... (docs/scaling.md)")
        out.append((step, composed, overrides))
    return out


def run_step(step: str, cfg: DictConfig, overrides: list[str] | None = None) -> dict:
    """Run one composed step; `overrides` (what it was composed from) go into its hints."""
    from ..runtime.cli import set_threads

    set_threads(cfg.get("threads"))
    with overrides_used(overrides if overrides is not None else []):
        if step in STEP_COMMANDS:  # edit, sample, interpolate; the others are train.py stages
            return COMMANDS[STEP_COMMANDS[step]].run(cfg)
        return run_stage(cfg)


def with_pair(cfg: DictConfig, overrides: list[str], run_dir: Path):
    """The interpolate step's config and overrides with `a` and `b` set to two of the training
    shapes (`collection.interpolation_pair`)."""
    a, b = interpolation_pair(run_dir / "shape_latent")
    cfg = cfg.copy()
    cfg.a, cfg.b = a, b
    print(f"interpolating {a} -> {b}", flush=True)
    return cfg, [*overrides, f"a={a}", f"b={b}"]


def headline(step: str, result: dict) -> dict:
    """The few numbers a person looks at first, per step."""
    r = result or {}
    if step == "fit":
        m = r.get("mean", {})
        return {k: m.get(k) for k in ("cd", "hd", "fscore", "watertight")}
    if step == "edit":
        return {k: r.get(k) for k in ("program", "shape", "eps_v", "eps_a")}
    if step == "annotate":
        rows = r if isinstance(r, list) else []
        return {"meshes": len(rows), "matched": sum("error" not in x for x in rows)}
    if step == "shape_latent":
        return {k: r.get(k) for k in ("l1", "param", "steps")}
    if step == "interpolate":
        return {k: r.get(k) for k in ("a", "b", "mesh_s_per_shape")}
    if step == "diffusion":
        return {k: r.get(k) for k in ("edm_loss_untrained", "edm_loss_ema", "steps")}
    return {k: r.get(k) for k in ("n", "latent_s_per_shape", "mesh_s_per_shape")}


def finished_steps(run_dir: Path) -> dict:
    """The steps an earlier run of this directory finished (its summary.json), for resume."""
    f = workspace.summary(run_dir)
    if not f.is_file():
        raise _fail(f"pipeline.resume: {f} does not exist",
                    fix="pass hydra.run.dir=<the directory of the run to resume>")
    return json.loads(f.read_text())["steps"]


def run_pipeline(cfg: DictConfig) -> dict:
    """Run the planned steps in order. With pipeline.resume=true, steps the run directory's
    summary.json lists as finished are kept, up to the first one that has to run; every step
    after that runs again, since it may read what changed."""
    run_dir = Path(cfg.run_dir).resolve()
    steps = planned_steps(cfg, run_dir)
    done = finished_steps(run_dir) if cfg.pipeline.get("resume") else {}
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(workspace.config(run_dir), OmegaConf.to_yaml(cfg.pipeline))
    summary = {"run_dir": str(run_dir), "steps": {}}
    rerun = False
    for k, (step, step_cfg, overrides) in enumerate(steps, 1):
        head = f"\n=== pipeline step {k}/{len(steps)}: {step} -> {run_dir / step}"
        if step in done and not rerun:
            print(f"{head} (finished earlier, kept)", flush=True)
            summary["steps"][step] = done[step]
            continue
        rerun = True
        print(head, flush=True)
        t0 = time.perf_counter()
        if step == "interpolate" and not {"a", "b"} & {o.split("=", 1)[0] for o in overrides}:
            step_cfg, overrides = with_pair(step_cfg, overrides, run_dir)
        result = run_step(step, step_cfg, overrides)
        if step == "annotate":
            check_annotated(result, step_cfg.data.path)
        seconds = time.perf_counter() - t0
        summary["steps"][step] = {"dir": str(run_dir / step), "seconds": seconds,
                                  **headline(step, result)}
        summary["total_s"] = sum(s["seconds"] for s in summary["steps"].values())
        atomic_write_text(workspace.summary(run_dir), json.dumps(summary, indent=2))
    summary["total_s"] = sum(s["seconds"] for s in summary["steps"].values())
    render_overview(run_dir, list(summary["steps"]), up=cfg.viz.up)
    print_summary(summary)
    return summary


def print_summary(summary: dict) -> None:
    print(f"\npipeline finished in {summary.get('total_s', 0) / 60:.1f} min: "
          f"{summary['run_dir']}")
    for step, s in summary["steps"].items():
        nums = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                         for k, v in s.items() if k not in ("dir", "seconds"))
        print(f"  {step:13s}{s['seconds']:8.1f} s   {nums}")
    print(f"  summary.json, overview.png in {summary['run_dir']}")


def render_overview(run_dir: Path, done: list[str], per_row: int = 4, up="auto") -> None:
    """overview.png: one row per step that made meshes (fitted / edited / generated /
    interpolated), `up`: `viz.up`; a row of shapes that record their body frame (a model
    trained on a collection written in one) stands on it (`viz.camera.frame_up`). A failed
    render (no off-screen OpenGL) is reported, not fatal."""
    import trimesh

    from ngc_gen.viz import render_grid, render_or_warn
    from ngc_gen.viz.camera import frame_up

    from .collection import collection_row

    def load(paths):
        return [trimesh.load(p, process=False) for p in paths[:per_row] if p.is_file()]

    def recorded_frame(step):
        f = workspace.summary(run_dir / step)
        return json.loads(f.read_text()).get("frame") if f.is_file() else None

    rows, labels, views, ups = [], [], [], []
    if "annotate" in done:
        meshes, frame_up_vec = collection_row(run_dir / "annotate", per_row)
        rows.append(meshes)
        labels.append("your meshes")
        views.append(None)
        ups.append(frame_up(up, None if frame_up_vec is None else {"up": frame_up_vec}))
    if "fit" in done:
        rows.append(load(sorted((workspace.meshes(run_dir / "fit")).glob("*.ply"))))
        labels.append("fitted")
        views.append(None)
        ups.append(up)
    if "edit" in done:
        rows.append(load([run_dir / "edit" / workspace.UNDEFORMED,
                          run_dir / "edit" / workspace.DEFORMED]))
        metrics = workspace.metrics(run_dir / "edit")
        program = json.loads(metrics.read_text()).get("program", "") if metrics.is_file() else ""
        labels.append(f"edit {program}: before, after")
        ups.append(frame_up(up, edited_frame(run_dir)))
        views.append(edit_row_view(run_dir, rows[-1], ups[-1]))
    for step, label in (("sample", "generated"), ("interpolate", "interpolated")):
        if step in done:
            shapes = sorted((run_dir / step).glob("*.ply"))
            if step == "interpolate" and len(shapes) > per_row:  # the ends and between
                idx = [round(k * (len(shapes) - 1) / (per_row - 1)) for k in range(per_row)]
                shapes = [shapes[k] for k in idx]
            rows.append(load(shapes))
            labels.append(label)
            views.append(None)
            ups.append(frame_up(up, recorded_frame(step)))
    kept = [(r, lab, v, u) for r, lab, v, u in zip(rows, labels, views, ups) if r]
    if not kept:
        return
    render_or_warn(render_grid, workspace.picture(run_dir, "pipeline"), [k[0] for k in kept],
                   labels=[k[1] for k in kept], frame="row", up=[k[3] for k in kept],
                   view=[k[2] for k in kept])


def edited_frame(run_dir: Path) -> dict | None:
    """The body frame edit/edited.yaml records (None: none, or no such file)."""
    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.errors import DataError

    try:
        return load_annotation(workspace.edited(run_dir / "edit")).frame
    except (DataError, OSError):
        return None


def edit_row_view(run_dir: Path, meshes: list, up="auto"):
    """The overview's camera for the edit row: edit.png's (`viz.camera.edit_view`, across the
    edited GCs' motion), from the fitted shape's GCs (the fit step's checkpoint) and the edited
    ones (`edit/edited.yaml`). None (the side view) when the edit did not edit the fit step's
    shape or a file is missing."""
    import numpy as np
    import yaml

    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.shape import load_shapes
    from ngc_gen.viz.camera import edit_view, resolve_up

    edit = run_dir / "edit"
    try:
        shape = yaml.safe_load((edit / workspace.PROGRAM).read_text())["shape"]
        before = load_shapes(run_dir / "fit")[shape].gcs
        after = load_annotation(workspace.edited(edit)).gcs
    except (OSError, KeyError, TypeError, ValueError):
        return None
    if len(meshes) != 2:
        return None
    u = resolve_up(up, meshes[:1])
    return edit_view(np.concatenate([np.asarray(m.vertices) for m in meshes]), before, after, u)
