"""Settings checked before the work starts, with light imports only: a run that cannot write its
results or has a malformed setting fails in a second with the setting to change, not after an
hour of preparation, training or extraction."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

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


# ---- what each entry point checks before torch loads ----------------------------------------
SAMPLE_MODES = ("generate", "interpolate", "mix", "condition")


def check_sample(cfg) -> None:
    """sample.py's settings (conf/sample.yaml, conf/mode/): the mode, every number it reads,
    the output folder and the run, in a second and before torch loads."""
    mode = cfg.get("mode")
    if mode not in SAMPLE_MODES:
        raise ConfigError("unknown mode", key="mode", value=mode,
                          fix=f"use one of mode={' | mode='.join(SAMPLE_MODES)}")
    check_extract(cfg)
    config_number(cfg, "seed", integer=True)
    if mode in ("generate", "condition"):
        config_number(cfg, "n", integer=True, minimum=1)
    if mode == "interpolate":
        config_number(cfg, "steps", integer=True, minimum=2)
    if mode == "mix":
        for key in ("t0", "t1", "w"):
            config_number(cfg, key, optional=True)
    if mode == "condition":
        config_number(cfg, "condition.strength", minimum=0)
        config_number(cfg, "condition.project_steps", integer=True, minimum=0)
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
