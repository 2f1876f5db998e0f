"""Stage `annotate`: automatic GCs for every mesh of a dataset (docs/autogc.md).

    python train.py stage=annotate data=folder data.path=DIR [annotate.write_beside=true]

Per mesh: `<name>.yaml` (an editable annotation; `prepare`/`fit` read it when it lies beside the
mesh) and `<name>_gcs.png` (the GCs drawn over the mesh) in the run directory, and with
`annotate.write_beside=true` beside the mesh too. A YAML beside a mesh that this stage did not
write (a hand annotation) is never overwritten. Prints a table: mesh, GCs, coverage, seconds,
and each mesh's GC names (what edit programs refer to).

With `annotate.template=T` (a template YAML with `place`, e.g.
datasets/animals/quadruped_transfer.yaml, or any annotated mesh's YAML) every mesh gets T's GCs
instead (ngc_gen/data/autogc/transfer/): the same names, order, degrees and keys, so one
shape-latent layout and one edit program for the folder. A mesh that does not match is one
line of the table and the rest are still annotated; the folder gets `transfer.png` (a colour
per template GC across the meshes) and `transfer.json` (the table). `annotate.export_template=
PATH` writes the template of the annotated meshes (averaged over the folder). A template from
annotated GCs (an annotated mesh's YAML, or the automatic GCs exported) is calibrated on its
mesh (ngc_gen/data/autogc/calibrate.py): the transfer ends each part where that annotation does.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from ngc_gen.data.annotations import Annotation
from ngc_gen.data.atomic import atomic_write_text
from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
from ngc_gen.data.autogc.calibrate import calibrate_ends
from ngc_gen.data.autogc.coverage import coverage_stats
from ngc_gen.data.autogc.orient import Orientation, gcs_orientation
from ngc_gen.data.autogc.template import Template, load_template
from ngc_gen.data.autogc.transfer import TransferSettings, export_template, transfer_template
from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import load_mesh, normalize
from ngc_gen.data.mesh.sampling import sample_surface

from ..runtime.config import instantiate
from ..runtime.next_hint import next_command
from ..runtime.training import start_run

HEADER = "# written by `train.py stage=annotate` (automatic GCs); edit freely, or delete to redo\n"
COVERAGE_SAMPLES = 50_000


def _meshes(dataset) -> list[tuple[str, str, float | None]]:
    """(name, mesh file or resource, bound) of every shape of the dataset."""
    if hasattr(dataset, "mesh_files"):
        return [(p.stem, str(p), dataset.bound) for p in dataset.mesh_files()]
    return [(a.name, a.mesh, a.bound) for a in dataset.shapes()]


def _write_yaml(ann: Annotation, path: Path) -> None:
    atomic_write_text(path, HEADER + ann.to_yaml(relative_to=path.parent.resolve()))


def _ours(path: Path) -> bool:
    """True if there is no file at path or this stage wrote it."""
    return not path.exists() or path.read_text(encoding="utf-8", errors="replace").startswith(HEADER)


GCS_CELL = (640, 560)  # <name>_gcs.png: two cells, 1280 x 560 (room for the GC names)


def _picture(ann: Annotation, path: Path, up="auto") -> Path | None:
    """The GCs over the mesh, and alone with their names (`up`: `viz.up`)."""
    import trimesh

    from ngc_gen.viz import gc_labels, gcs_surface, render_grid, render_or_warn

    mesh, _, _ = ann.load_mesh()
    shell = gcs_surface(ann.gcs)
    return render_or_warn(render_grid, path,
                          [[(mesh, shell), (trimesh.Trimesh(shell.vertices, shell.faces), None,
                                            gc_labels(ann.gcs))]],
                          col_titles=[f"{ann.name}: {len(ann.gcs)} GCs over the mesh",
                                      "the GCs by name"], frame="row", up=up, cell=GCS_CELL)


def _surface(mesh, seed: int) -> np.ndarray:
    points, _ = sample_surface(mesh.vertices, mesh.faces, COVERAGE_SAMPLES, np.random.default_rng(seed + 1))
    return points


def load_transfer_template(path: str, d: dict) -> Template:
    """annotate.template: a template YAML, or an annotated mesh's YAML (its GCs become the
    template, its mesh says where they sit)."""
    p = Path(path)
    if not p.is_file():
        raise DataError("template file not found", path=p, field="annotate.template",
                        fix="give a template YAML (the shipped one: datasets/animals/"
                            "quadruped_transfer.yaml) or an annotated mesh's YAML")
    import yaml

    try:
        raw = yaml.safe_load(p.read_text(encoding="utf-8"))
    except yaml.YAMLError:
        raw = None
    if isinstance(raw, dict) and "mesh" in raw and isinstance(raw.get("gcs"), list):
        ann = load_annotation(p)
        mesh, _, _ = ann.load_mesh()
        points = _surface(mesh, int(d.get("seed", 0)))
        o = gcs_orientation(ann.gcs, points, d.get("up"), d.get("front"))
        t = export_template([(ann.gcs, points, o)], ann.name)
        t = calibrate_ends(t, [(ann.name, mesh, ann.gcs)], TransferSettings.from_config(d))
        return Template(t.name, t.gcs, t.version, str(p), t.frame)
    return load_template(p)


def run_annotate(cfg: DictConfig) -> list[dict]:
    run_dir = start_run(cfg)
    conf = OmegaConf.to_container(cfg.annotate, resolve=True)
    if conf.get("template"):
        return run_transfer(cfg, run_dir, conf)
    settings = AutoGCSettings.from_config(conf)
    beside = bool(cfg.annotate.get("write_beside", False))
    dataset = instantiate(cfg.data, "data")
    rows = []
    for name, mesh, bound in _meshes(dataset):
        t0 = time.perf_counter()
        ann = auto_annotation(mesh, name=name, bound=bound, settings=settings)
        seconds = time.perf_counter() - t0
        normalized, _, _ = normalize(load_mesh(mesh), bound)
        points, _ = sample_surface(normalized.vertices, normalized.faces, COVERAGE_SAMPLES,
                                   np.random.default_rng(settings.seed + 1))
        stats = coverage_stats(ann.gcs, points)
        _write_yaml(ann, run_dir / f"{name}.yaml")
        _picture(ann, run_dir / f"{name}_gcs.png", cfg.viz.up)
        wrote = []
        if beside and not Path(mesh).exists():
            wrote.append("not beside (a resource)")
        elif beside:
            target = Path(mesh).with_suffix(".yaml")
            if _ours(target):
                _write_yaml(ann, target)
                _picture(ann, target.with_name(f"{name}_gcs.png"), cfg.viz.up)
                wrote.append(f"beside: {target}")
            else:
                wrote.append(f"kept the hand annotation {target}")
        rows.append({"mesh": name, "n_gcs": len(ann.gcs), "coverage": stats["coverage"],
                     "overlap": stats["overlap"], "seconds": seconds, "gc_names": ann.gc_names,
                     "notes": wrote})
    print_table(rows, settings)
    if conf.get("export_template"):
        first = load_annotation(run_dir / f"{rows[0]['mesh']}.yaml")
        mesh, _, _ = normalize(load_mesh(first.mesh_path), first.bound)
        points = _surface(mesh, settings.seed)
        o = gcs_orientation(first.gcs, points, conf.get("up"), conf.get("front"))
        t = export_template([(first.gcs, points, o)], first.name)
        t = calibrate_ends(t, [(first.name, mesh, first.gcs)], TransferSettings.from_config(conf))
        _write_template(t, Path(conf["export_template"]), f"the automatic GCs of {first.name}")
    print(f"run directory: {run_dir}")
    return rows


def _write_template(t: Template, path: Path, what: str) -> None:
    atomic_write_text(path, f"# template written by `train.py stage=annotate` from {what}\n"
                            f"# use it: python train.py stage=annotate data=folder data.path=DIR "
                            f"annotate.template={path}\n" + t.to_yaml())
    print(f"template: {path}")


def _hand_annotation(mesh_file: str) -> Path | None:
    """The `<name>.yaml` beside a mesh that a user wrote (with GCs; not this stage's)."""
    p = Path(mesh_file).with_suffix(".yaml")
    if not p.is_file() or _ours(p):
        return None
    import yaml

    try:
        d = yaml.safe_load(p.read_text(encoding="utf-8"))
    except yaml.YAMLError:
        return None
    return p if isinstance(d, dict) and d.get("gcs") else None


def _transfer_one(name: str, mesh_file: str, bound, template: Template, st) -> tuple:
    """(annotation in the template's frame, its mesh, the Transfer) of one mesh; DataError
    when it does not match or its frame override cannot be read."""
    from ngc_gen.data.autogc.frame import read_override, record, written

    override, _ = read_override(mesh_file) if Path(mesh_file).exists() else (None, None)
    raw = load_mesh(mesh_file)
    mesh, center, scale = normalize(raw, bound)
    tr = transfer_template(mesh, template, st, where=str(mesh_file), override=override)
    mesh_w, gcs_w = written(raw, center, scale, tr.gcs, tr.rotation, bound)
    frame = record(tr.orientation, Orientation(template.up, template.front), tr.source)
    ann = Annotation(name=name, mesh=str(Path(mesh_file).resolve()), gcs=gcs_w, bound=bound,
                     frame=frame)
    return ann, mesh_w, tr


def _beside(ann: Annotation, mesh_file: str, on: bool, up) -> str:
    """write_beside: the annotation and its picture beside the mesh, never over a user's."""
    if not on:
        return ""
    if not Path(mesh_file).exists():
        return "not beside (a resource)"
    target = Path(mesh_file).with_suffix(".yaml")
    if not _ours(target):
        return f"kept {target} (yours)"
    _write_yaml(ann, target)
    _picture(ann, target.with_name(f"{ann.name}_gcs.png"), up)
    return f"beside: {target}"


def run_transfer(cfg: DictConfig, run_dir: Path, conf: dict) -> list[dict]:
    """annotate.template: the template's GCs on every mesh (module docstring)."""
    template = load_transfer_template(conf["template"], conf)
    st = TransferSettings.from_config(conf)
    dataset = instantiate(cfg.data, "data")
    rows, cells, shapes, bad = [], [], [], []
    tf_up = [float(x) for x in template.up]
    for name, mesh_file, bound in _meshes(dataset):
        t0 = time.perf_counter()
        hand = _hand_annotation(mesh_file)
        try:
            if hand is not None:  # a user's annotation: kept as it is, and used
                ann = load_annotation(hand)
                _write_yaml(ann, run_dir / f"{name}.yaml")
                rows.append({"mesh": name, "hand": str(hand), "seconds": time.perf_counter() - t0})
                print(f"{name}: kept your annotation {hand}", flush=True)
                continue
            ann, mesh, tr = _transfer_one(name, mesh_file, bound, template, st)
        except DataError as e:
            rows.append({"mesh": name, "error": str(e), "seconds": time.perf_counter() - t0})
            print(f"{name}: refused: {e}", flush=True)
            if e.field is not None and e.field.startswith("frame"):
                bad.append(e)
            continue
        seconds = time.perf_counter() - t0
        points = _surface(mesh, st.seed)
        stats = coverage_stats(ann.gcs, points)
        _write_yaml(ann, run_dir / f"{name}.yaml")
        _picture(ann, run_dir / f"{name}_gcs.png", tf_up)
        note = _beside(ann, mesh_file, bool(conf.get("write_beside")), tf_up)
        cells.append((f"{name} ({tr.orientation.describe()})", mesh, ann.gcs, tf_up))
        shapes.append((ann.gcs, points, Orientation(template.up, template.front, ("given", "given"))))
        rows.append({"mesh": name, "matched": tr.matched, "missing": tr.missing, "cost": tr.cost,
                     "coverage": stats["coverage"], "seconds": seconds, "frame": ann.frame,
                     "confidence": tr.confidence, "warnings": tr.warnings, "note": note,
                     "up": tr.orientation.up.tolist(), "front": tr.orientation.front.tolist()})
        print(f"{name}: {len(tr.matched)}/{len(template.names)} matched, confidence "
              f"{tr.confidence:.2f}, {tr.orientation.describe()}, {seconds:.1f} s"
              + "".join(f"; warning: {w}" for w in tr.warnings) + (f"; {note}" if note else ""),
              flush=True)
    print_transfer_table(rows, template)
    _transfer_outputs(run_dir, rows, cells, shapes, template, conf)
    print(f"run directory: {run_dir}")
    print("next: " + next_command("train.py", ["stage=shape_latent", "data=folder",
                                               f"data.path={run_dir}"],
                                  drop=("data", "annotate")))
    if bad:
        raise DataError(f"{len(bad)} mesh(es) not annotated, their frame override is wrong; first: "
                        f"{bad[0].what}", path=bad[0].path, field=bad[0].field, fix=bad[0].fix)
    return rows


def _transfer_outputs(run_dir: Path, rows, cells, shapes, template: Template, conf: dict) -> None:
    """transfer.json, transfer.png and (annotate.export_template) the averaged template."""
    import json

    atomic_write_text(run_dir / "transfer.json", json.dumps(
        {"template": template.source or template.name, "meshes": rows}, indent=1))
    if cells:
        from ngc_gen.viz.gc_colors import render_gc_collection
        from ngc_gen.viz.render import render_or_warn

        render_or_warn(render_gc_collection, run_dir / "transfer.png",
                       [c[:3] for c in cells], template.names, up=[c[3] for c in cells])
    if conf.get("export_template") and shapes:
        t = export_template(shapes, template.name, template)
        _write_template(t, Path(conf["export_template"]),
                        f"{len(shapes)} meshes annotated with template {template.source or template.name}")


def print_transfer_table(rows: list[dict], template: Template) -> None:
    print(f"\ntemplate {template.name} ({template.source}): GCs {', '.join(template.names)}")
    print(f"{'mesh':24s} {'matched':>8s} {'confidence':>10s} {'cost':>6s} {'coverage':>9s} "
          f"{'seconds':>8s}  missing")
    for r in rows:
        if "error" in r or "hand" in r:
            what = ("refused", r["error"]) if "error" in r else ("yours", f"kept {r['hand']}")
            print(f"{r['mesh']:24s} {what[0]:>8s} {'':>10s} {'':>6s} {'':>9s} {r['seconds']:8.2f}  "
                  f"{what[1]}")
            continue
        print(f"{r['mesh']:24s} {len(r['matched']):4d}/{len(template.names):<3d} "
              f"{r['confidence']:10.2f} {r['cost']:6.2f} {100 * r['coverage']:8.3f}% "
              f"{r['seconds']:8.2f}  {', '.join(r['missing']) or '-'}")


def print_table(rows: list[dict], settings: AutoGCSettings) -> None:
    print(f"\n{'mesh':24s} {'GCs':>4s} {'coverage':>9s} {'seconds':>8s}   method {settings.method}")
    for r in rows:
        print(f"{r['mesh']:24s} {r['n_gcs']:4d} {100 * r['coverage']:8.3f}% {r['seconds']:8.2f}")
    for r in rows:
        print(f"{r['mesh']}: GCs {', '.join(r['gc_names'])}" + "".join(f"; {n}" for n in r["notes"]))
