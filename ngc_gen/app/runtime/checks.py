"""Settings checked before the work starts, with light imports only: a run that cannot write its
results or has a malformed setting fails in a second with the setting to change, not after an
hour of preparation, training or extraction."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ngc_gen.data.errors import DataError

from .errors import ConfigError


def check_writable(path, key: str) -> Path:
    """`path` (a folder to be written, created later if missing) can be written: its nearest
    existing ancestor is a folder in which a file can be created. Creates nothing that stays.
    ConfigError naming `key` (the setting that chose the folder) otherwise."""
    path = Path(path).expanduser().absolute()
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    fix = f"pass {key}=<a folder you can write>"
    if not probe.is_dir():
        raise ConfigError(f"{probe} is a file, not a folder, so {path} cannot be created",
                          key=key, value=str(path), fix=fix)
    try:
        with tempfile.TemporaryFile(dir=probe):
            pass
    except OSError as e:
        raise ConfigError(f"cannot write in {probe} ({e.strerror or e})", key=key,
                          value=str(path), fix=fix) from None
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(f"no permission to write in {probe}", key=key, value=str(path),
                          fix=fix)
    return path


def trainer_steps(cfg) -> int:
    """trainer.max_steps as an int (ConfigError if it is not a whole number >= 1)."""
    return config_number(cfg, "trainer.max_steps", integer=True, minimum=1)

def config_number(cfg, key: str, *, integer: bool = False, minimum=None, maximum=None,
                  strict_minimum: bool = False, optional: bool = False):
    """The number at `key` of a composed config, read by the project's one rule for numbers
    (`ngc_gen.values.read_number`: a quoted number is refused, as in programs and
    annotations); None if `optional` and the key is null. ConfigError naming the key."""
    from omegaconf import OmegaConf

    from ngc_gen.values import NumberError, read_number

    value = OmegaConf.select(cfg, key, default=None)
    if value is None and optional:
        return None
    try:
        return read_number(value, integer=integer, minimum=minimum, maximum=maximum,
                           strict_minimum=strict_minimum)
    except NumberError as e:
        raise ConfigError(e.what, key=key, value=value, fix=e.config_fix(key)) from None


def check_resolution(cfg, key: str, method: str = "sparse") -> int:
    """The grid resolution at `key`: a whole number >= 8 whose extraction fits in the memory
    available now (`ngc_gen.extract.budget`), checked before anything is allocated or loaded.
    ConfigError naming the key and the largest resolution that fits."""
    from ngc_gen.extract.budget import GridTooLarge
    from ngc_gen.extract.budget import check_resolution as fits

    resolution = config_number(cfg, key, integer=True, minimum=8)
    try:
        fits(resolution, method)
    except GridTooLarge as e:
        raise ConfigError(e.reason, key=key, value=resolution,
                          fix=f"pass {key}={e.largest} or less, or free memory") from None
    return resolution


def check_extract(cfg, prefix: str = "extract") -> None:
    """The extraction settings of a config (conf/extract/default.yaml): resolution (a whole
    number that fits in memory), bound > 0, chunk (null or >= 1)."""
    check_resolution(cfg, f"{prefix}.resolution")
    config_number(cfg, f"{prefix}.bound", minimum=0, strict_minimum=True)
    config_number(cfg, f"{prefix}.chunk", integer=True, minimum=1, optional=True)


def check_threads(threads) -> int | str | None:
    """The `threads` setting, checked without torch: auto, null or a whole number >= 1 (the
    project's rule for numbers, `ngc_gen.values`). ConfigError naming the key otherwise."""
    if threads is None or str(threads) == "auto":
        return None if threads is None else "auto"
    from ngc_gen.values import NumberError, read_number

    try:
        return read_number(threads, integer=True, minimum=1)
    except NumberError:
        raise ConfigError(f"threads must be >= 1, auto or null, got {threads}", key="threads",
                          value=threads, fix="pass threads=auto (default), threads=1 (shared "
                          "machine) or threads=null (all cores)") from None


# ---- what each entry point checks before torch loads ----------------------------------------
def check_sample(cfg) -> None:
    """sample.py's settings (conf/sample.yaml, conf/mode/): the mode and its settings
    (`mode_settings`), every number it reads, the output folder and the run, in a second and
    before torch loads."""
    from ..stages.settings import mode_settings

    mode_settings(cfg)
    check_extract(cfg)
    config_number(cfg, "seed", integer=True)
    config_number(cfg, "sampler.steps", integer=True, minimum=1)
    for key in ("sampler.churn", "sampler.S_min", "sampler.S_noise"):
        config_number(cfg, key, minimum=0)
    config_number(cfg, "sampler.S_max", optional=True)
    check_sample_run(cfg)
    check_writable(cfg.out_dir, "out_dir")


SAMPLE_RUN_FIX = ("pass run=<dir> of a `train.py stage=diffusion` run (or of a "
                  "`stage=shape_latent` run for interpolation / mixing between training shapes)")
FIT_RUN_FIX = ("pass run=<dir> (or its checkpoints/last.ckpt) of a `train.py stage=fit` run, "
               "or run=<a sample.py output directory>")


def check_sample_run(cfg) -> None:
    """sample.py's run (a diffusion or shape-latent run), its shape_latent_run and latents file
    exist and are of the right kind (read without torch: `ngc_gen.lit.peek`)."""
    from ngc_gen.lit.peek import check_kind, resolve_checkpoint

    kinds = {"ngc_gen.diffusion": "a `train.py stage=diffusion` run",
             "ngc_gen.shape_latent": "a `train.py stage=shape_latent` run"}
    check_kind(resolve_checkpoint(cfg.get("run"), fix=SAMPLE_RUN_FIX, what="run"), kinds,
               SAMPLE_RUN_FIX)
    sl = cfg.get("shape_latent_run")
    if sl is not None:
        fix = "pass shape_latent_run=<dir> of a `train.py stage=shape_latent` run"
        check_kind(resolve_checkpoint(sl, fix=fix, what="shape_latent_run"),
                   {"ngc_gen.shape_latent": kinds["ngc_gen.shape_latent"]}, fix)
    latents = cfg.get("latents")
    if latents is not None and not Path(str(latents)).is_file():
        raise ConfigError("no such file", key="latents", value=str(latents),
                          fix="pass latents=<the latents.pt of a `train.py stage=reconstruct` "
                              "run>")
    if cfg.get("mode") == "condition":
        gcs = cfg.get("gcs")
        if gcs is None or not Path(str(gcs)).is_file():
            raise ConfigError("no such file" if gcs is not None else "not set", key="gcs",
                              value=gcs, fix="pass gcs=<a YAML of GCs: a dataset annotation, a "
                                             "sample's YAML or edit.py's edited.yaml>")


def check_fit_run(run) -> Path:
    """edit.py's and the editor's run: a fit run directory, a checkpoint file or a sample.py
    output folder, holding a fitting checkpoint (kind read without torch). Returns the file."""
    from ngc_gen.lit.peek import check_kind

    from .checkpoints import fit_checkpoint

    path = fit_checkpoint(run)
    check_kind(path, {"ngc_gen.autodecoder": "a `train.py stage=fit` run"}, FIT_RUN_FIX)
    return path


LOOPBACK = ("127.0.0.1", "localhost", "::1")


def editor_out_dir(editor) -> Path:
    """Where the editor's save / export write: editor.out_dir, or outputs/editor/<date_time>."""
    import time

    out = editor.get("out_dir")
    return Path(str(out)) if out else Path("outputs/editor") / time.strftime("%Y-%m-%d_%H-%M-%S")


def check_editor(cfg) -> None:
    """`edit.py viewer=true`: the editor's settings (conf/editor/default.yaml) before the
    checkpoint and viser load: the bind address (loopback unless editor.allow_remote=true),
    the port, the resolutions (numbers that fit in memory), the save folder (writable), the
    run and the generator run."""
    editor = cfg.editor
    host = str(editor.get("host"))
    if host not in LOOPBACK and not editor.get("allow_remote", False):
        raise ConfigError("binds the editor to a non-loopback address: anyone who can reach "
                          "this machine could edit and write files through it", key="editor.host",
                          value=host, fix="keep editor.host=127.0.0.1 and reach it through `ssh "
                          "-L 8080:127.0.0.1:8080 <host>`, or pass editor.allow_remote=true if "
                          "the network is yours")
    config_number(cfg, "editor.port", integer=True, minimum=0, maximum=65535)
    check_resolution(cfg, "editor.preview_resolution")
    check_resolution(cfg, "editor.refine_resolution")
    config_number(cfg, "editor.refine_delay_s", minimum=0)
    config_number(cfg, "editor.bound", minimum=0, strict_minimum=True)
    config_number(cfg, "editor.chunk", integer=True, minimum=1, optional=True)
    check_writable(editor_out_dir(editor), "editor.out_dir")
    if cfg.get("run") is not None:
        check_fit_run(cfg.run)
    generator = editor.get("generator")
    if generator is not None:
        from ngc_gen.lit.peek import check_kind, resolve_checkpoint

        fix = "pass editor.generator=<dir> of a `train.py stage=diffusion` run"
        check_kind(resolve_checkpoint(generator, fix=fix, what="editor.generator"),
                   {"ngc_gen.diffusion": "a `train.py stage=diffusion` run",
                    "ngc_gen.shape_latent": "a `train.py stage=shape_latent` run"}, fix)
    elif cfg.get("run") is None:
        raise ConfigError("no run given", key="run", value=None,
                          fix="pass run=<fit run dir or checkpoint, or a sample.py output dir> "
                              "or editor.generator=<diffusion run>")


def edit_output_dir(cfg, program_name: str) -> Path:
    """edit.py's `out_dir`, or outputs/edit/<program>/<date_time> (relative to the cwd)."""
    import time

    out_dir = Path(cfg.out_dir) if cfg.get("out_dir") else \
        Path("outputs/edit") / program_name / time.strftime("%Y-%m-%d_%H-%M-%S")
    return out_dir.resolve()


def check_edit(cfg) -> None:
    """edit.py's settings before torch loads: the program's structure, the output folder, the
    run (a fitting checkpoint), the extraction settings; the editor's with viewer=true."""
    check_extract(cfg)
    if cfg.get("viewer"):
        check_editor(cfg)
        return
    from .programs import program_from_config

    parts = program_from_config(cfg)
    check_writable(edit_output_dir(cfg, parts["name"]), "out_dir")
    check_fit_run(cfg.get("run"))
    shape = cfg.get("shape")
    if shape is not None and not isinstance(shape, str):
        raise ConfigError("must be a shape name", key="shape", value=shape,
                          fix="pass shape=<name> (edit.py lists the names if it is wrong)")


# ---- what train.py's stages check before torch loads (their registry entries name these) ----
def check_resume_from(cfg, kind: str) -> None:
    """ckpt_path, when given, is a checkpoint of this stage's `kind` (read without torch)."""
    from ngc_gen.lit.kinds import only
    from ngc_gen.lit.peek import check_kind, resolve_checkpoint

    if cfg.get("ckpt_path") is None:
        return
    fix = ("pass ckpt_path=<run dir> or <run>/checkpoints/last.ckpt of an interrupted run "
           "of the same stage")
    check_kind(resolve_checkpoint(cfg.ckpt_path, what="checkpoint to resume from", fix=fix),
               only(kind), fix)


def check_shape_latent(cfg) -> None:
    """stage=shape_latent: shape_latent.init_decoder, when given, is a fit run; the annotation
    files the data config reads share one body frame (YAML only, `check_frames`)."""
    from omegaconf import OmegaConf

    from ngc_gen.lit.kinds import FIT, only
    from ngc_gen.lit.peek import check_kind, resolve_checkpoint

    if cfg.get("data") is not None:
        check_frames(OmegaConf.to_container(cfg.data, resolve=True, throw_on_missing=True))
    init = cfg.get("shape_latent", {}).get("init_decoder")
    if init is not None:
        fix = "pass shape_latent.init_decoder=<a `train.py stage=fit` run or its last.ckpt>"
        check_kind(resolve_checkpoint(init, fix, "fit run"), only(FIT), fix)


def check_diffusion_stage(cfg) -> None:
    """stage=diffusion: shape_latent_run is a shape-latent run; the diffusion settings name
    known choices."""
    from ngc_gen.lit.kinds import SHAPE_LATENT, only
    from ngc_gen.lit.peek import check_kind, resolve_checkpoint

    fix = ("pass the run directory (or checkpoints/last.ckpt) of a `train.py "
           "stage=shape_latent` run")
    path = resolve_checkpoint(cfg.get("shape_latent_run"), fix, "shape-latent run")
    check_kind(path, only(SHAPE_LATENT), fix)
    if cfg.get("diffusion") is not None:
        check_diffusion(cfg.diffusion)


def check_diffusion(d) -> None:
    """diffusion.standardise and diffusion.pca_complete name known choices."""
    from ngc_gen.lit.diffusion_options import PCA_COMPLETE, STANDARDISE

    for key, allowed in (("standardise", STANDARDISE), ("pca_complete", PCA_COMPLETE)):
        if d.get(key) is not None and d.get(key) not in allowed:
            raise ConfigError("unknown choice", key=f"diffusion.{key}", value=d.get(key),
                              fix=f"choose one of {', '.join(allowed)}")
    check_pose_transfer(d.get("pose_transfer"))


def check_pose_transfer(pt) -> None:
    """diffusion.pose_transfer: null, or bodies (a non-empty list of names) and the GC template
    file the shapes were made with (its GCs' parents)."""
    from omegaconf import ListConfig

    if not pt:
        return
    key = "diffusion.pose_transfer"
    bodies = pt.get("bodies")
    if not isinstance(bodies, (list, tuple, ListConfig)) or not bodies \
            or not all(isinstance(b, str) and b for b in bodies):
        raise ConfigError("needs a non-empty list of body names", key=f"{key}.bodies",
                          value=bodies, fix="list the names the shape names start with, e.g. "
                          "diffusion.pose_transfer.bodies=[wolf,horse]")
    if pt.get("poses") not in (None, "missing", "all"):
        raise ConfigError("must be missing (the poses a body lacks) or all", key=f"{key}.poses",
                          value=pt.get("poses"), fix=f"pass {key}.poses=missing")
    template = pt.get("template")
    if not template or not Path(str(template)).is_file():
        raise ConfigError("GC template file not found", key=f"{key}.template", value=template,
                          fix="pass the template the shapes were made with (the animals': "
                          "datasets/animals/quadruped.yaml), or diffusion.pose_transfer=null")


RECONSTRUCT_RUN_FIX = ("pass run=<dir or checkpoint> of a `train.py stage=fit` run (codes) or a "
                       "`train.py stage=shape_latent` run (latents)")


def check_reconstruct(cfg) -> None:
    """stage=reconstruct: `run` is a fit or shape-latent run (its kind read without torch) and
    the `reconstruct` group builds (`ReconstructSettings`: numbers, gcs=input|decoded)."""
    from ngc_gen.lit.kinds import FIT, SHAPE_LATENT, only
    from ngc_gen.lit.peek import check_kind, resolve_checkpoint

    from .config import instantiate

    path = resolve_checkpoint(cfg.get("run"), fix=RECONSTRUCT_RUN_FIX,
                              what="run to reconstruct into")
    check_kind(path, only(FIT, SHAPE_LATENT), RECONSTRUCT_RUN_FIX)
    instantiate(cfg.reconstruct, "reconstruct")


def check_data_files(data) -> None:
    """The files the data config names (annotation YAMLs, mesh headers, data=folder's meshes)."""
    from omegaconf import OmegaConf

    check_data(OmegaConf.to_container(data, resolve=True, throw_on_missing=True))


# ---- a data config's files: each annotation YAML parses and names its mesh and GCs, each mesh
# file exists and its header and data are whole (`ngc_gen.data.mesh.header`), GC names are
# unique; the words of the full check (`load_annotation`, `load_mesh`)
RESOURCE_PREFIXES = ("pyvista:",)  # shipped meshes (`mesh.io.RESOURCE_SCHEMES`): read later


def _mesh_of(mesh: Path, owner) -> None:
    from ngc_gen.data.mesh.header import check_mesh_file

    try:
        check_mesh_file(mesh)
    except DataError as e:  # the words of prepare's `_in_context`
        raise DataError(f"{e.what} (mesh of {owner})", path=e.path, field="mesh",
                        fix=e.fix) from None


def check_annotation_file(path) -> None:
    """An annotation YAML (docs/gcs.md): a mapping with `mesh` and a non-empty `gcs` list of
    uniquely named GCs, whose mesh file passes `check_mesh_file`. DataError naming the file."""
    from ngc_gen.data.annotation_file import read_annotation_yaml

    path = Path(path)
    d = read_annotation_yaml(path)
    if not isinstance(d, dict):
        return  # load_annotation explains what an annotation must be
    gcs = d.get("gcs")
    if isinstance(gcs, list):
        names = [g.get("name") for g in gcs if isinstance(g, dict)]
        dupes = sorted({str(n) for n in names if n is not None and names.count(n) > 1})
        if dupes:
            raise DataError(f"GC names {dupes} appear more than once", path=path, gc=dupes[0],
                            field="name", fix="give every GC a unique name")
    mesh = d.get("mesh")
    if isinstance(mesh, str) and mesh and not mesh.startswith(RESOURCE_PREFIXES):
        file = Path(mesh).expanduser()
        _mesh_of(file if file.is_absolute() else path.parent / file, path)


def check_data(node) -> None:
    """Every file a `data` config (conf/data/*.yaml, resolved to a dict) will read: the
    annotations of AnnotatedShapes, the meshes (and annotations beside them) of MeshFolder,
    the parts of Combined and the base of SingleGC. Generated datasets (Creatures) have no
    user files."""
    from ngc_gen.data.mesh_folder import mesh_files, run_annotations

    if isinstance(node, list):
        for part in node:
            check_data(part)
        return
    if not isinstance(node, dict):
        return
    target = str(node.get("_target_", "")).rsplit(".", 1)[-1]
    if target == "AnnotatedShapes":
        for a in node.get("annotations") or []:
            check_annotation_file(a)
    elif target == "MeshFolder" and run_annotations(node["path"]):  # an annotate run directory
        for a in run_annotations(node["path"]):
            check_annotation_file(a)
    elif target == "MeshFolder":
        for mesh in mesh_files(node["path"]):
            yml = mesh.with_suffix(".yaml")
            if yml.exists():
                check_annotation_file(yml)
            else:
                _mesh_of(mesh, f"automatic annotation '{mesh.stem}'")
    elif target == "Combined":
        check_data(node.get("parts"))
    elif target == "SingleGC":
        check_data(node.get("base"))


def check_frames(node) -> None:
    """The annotation files a MeshFolder or AnnotatedShapes config reads share one body frame
    (`body_frame.collection_frame` on their `frame` keys, YAML only): what a generator needs,
    refused in a second instead of after the meshes are read. A mesh without a YAML has no
    frame of its own and does not count."""
    from ngc_gen.data.annotation_file import read_annotation_yaml
    from ngc_gen.data.body_frame import collection_frame
    from ngc_gen.data.mesh_folder import mesh_files, run_annotations

    if not isinstance(node, dict):
        return
    target = str(node.get("_target_", "")).rsplit(".", 1)[-1]
    if target == "AnnotatedShapes":
        files = [Path(a) for a in node.get("annotations") or []]
    elif target == "MeshFolder":
        files = run_annotations(node["path"]) or [
            m.with_suffix(".yaml") for m in mesh_files(node["path"])
            if m.with_suffix(".yaml").exists()]
    else:
        return
    frames = []
    for f in files:
        d = read_annotation_yaml(f)
        frame = d.get("frame") if isinstance(d, dict) else None
        ok = isinstance(frame, dict) and all(
            isinstance(frame.get(k), list) and len(frame[k]) == 3 for k in ("up", "front"))
        frames.append((f.stem, frame if ok else None))
    collection_frame(frames)
