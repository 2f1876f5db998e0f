"""Hydra/OmegaConf glue: composing the project's configs from Python, and the resolvers
(`ngc_root` anchors data paths at the checkout; `ngc_groups` lists an entry point's groups in its
--help; `ngc_stem` names a mesh folder's caches after it), registered by the entry points and
`compose_config`."""
from __future__ import annotations

import os
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from ngc_gen.conf.defaults import CONF_DIR  # the checkout's conf/, beside train.py, edit.py, sample.py


def repo_root() -> Path:
    """The checkout this package runs from (shipped datasets, default caches: `paths`);
    override with the NGC_ROOT environment variable."""
    return Path(os.environ.get("NGC_ROOT", Path(__file__).resolve().parents[3]))


def config_groups() -> str:
    """`${ngc_groups:}` (conf/hydra/help/ngc.yaml): one line per config group the running entry
    point's primary config chose from, with the options its config sources hold (conf/, and the
    package's ngc_gen/conf through the search path). Hydra's own listing shows every group under
    conf/, including the ones this entry point never reads."""
    from hydra.core.hydra_config import HydraConfig

    runtime = HydraConfig.get().runtime
    groups = sorted(g for g in runtime.choices if not g.startswith("hydra"))
    return "\n".join(f"{g}: {', '.join(group_options(g, runtime.config_sources))}"
                     for g in groups)


def group_options(group: str, sources) -> list[str]:
    """The option names (YAML file stems) of `group` in Hydra's file and pkg config sources."""
    import importlib.resources

    names = set()
    for src in sources:
        if src.schema == "file":
            folder = Path(src.path) / group
        elif src.schema == "pkg" and src.provider != "hydra":
            folder = importlib.resources.files(src.path).joinpath(group)
        else:
            continue
        if folder.is_dir():
            names |= {f.name[:-5] for f in folder.iterdir() if f.name.endswith(".yaml")}
    return sorted(names)


def folder_name(path) -> str:
    """`${ngc_stem:<path>}` (conf/data/folder.yaml): the name of a folder of the user's meshes,
    which names its caches (`.cache/prepared/<name>`), instead of one name for every folder."""
    name = Path(str(path)).expanduser().absolute().name
    return name or "folder"


def register_resolvers() -> None:
    """Register the project's OmegaConf resolvers (`ngc_root`, `ngc_groups`): process-wide state,
    so called by the entry points before Hydra composes and by `compose_config`, never at
    import time."""
    if not OmegaConf.has_resolver("ngc_root"):
        OmegaConf.register_new_resolver("ngc_root", lambda: str(repo_root()))
    if not OmegaConf.has_resolver("ngc_groups"):
        OmegaConf.register_new_resolver("ngc_groups", config_groups)
    if not OmegaConf.has_resolver("ngc_stem"):
        OmegaConf.register_new_resolver("ngc_stem", folder_name)


def compose_config(config_name: str = "train", overrides: list[str] | None = None):
    """Compose one of the project's Hydra configs from Python (benchmarks, tests, notebooks, the
    pipeline stage inside a running `@hydra.main` app, whose Hydra state is restored after).
    `run_dir` / `out_dir` must be given as overrides: there is no Hydra run directory."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    register_resolvers()
    running = GlobalHydra.instance().hydra if GlobalHydra.instance().is_initialized() else None
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(version_base="1.3", config_dir=str(CONF_DIR)):
            return compose(config_name=config_name, overrides=overrides or [])
    finally:
        if running is not None:
            GlobalHydra.instance().hydra = running


def instantiate(node, what: str, **kwargs):
    """hydra.utils.instantiate, with a value the target rejects (trainer.max_steps=abc, an
    unknown argument) reported as a ConfigError naming the config group `what`."""
    import hydra
    from hydra.errors import InstantiationException

    from .errors import ConfigError, user_error_types

    try:
        return hydra.utils.instantiate(node, **kwargs)
    except InstantiationException as e:
        cause = e.__cause__ if e.__cause__ is not None else e
        if isinstance(cause, user_error_types()):  # already says what and how to fix
            raise cause from None
        raise ConfigError(f"config group '{what}' does not build: "
                          f"{' '.join(str(cause).split())[:300]}",
                          fix=f"check the {what}.* settings (python train.py --help)") from None


def instantiate_group(node: DictConfig, runner_keys: tuple[str, ...] = (), **runtime):
    """The object a config group option names by `_target_` (its interpolations resolved in the
    whole config), built with `runtime` arguments (sizes known only from the data); the group's
    `runner_keys` are settings the stage reads itself and are left out. Arguments arrive as
    plain dicts and lists (`_convert_="all"`), so hyper-parameters a module records stay
    loadable with weights_only=True."""
    d = OmegaConf.to_container(node, resolve=True)
    for k in runner_keys:
        d.pop(k, None)
    what = node._key() if hasattr(node, "_key") and node._key() else "model"
    return instantiate(d, str(what), _convert_="all", **runtime)


def sparse_settings(node):
    """The sparse extractor's refinement (`ngc_gen.extract.SparseSettings`) from a config's
    `extract.sparse` node (conf/extract/default.yaml, where its defaults live); a bad value is
    a ConfigError that names the key."""
    return instantiate(node, "extract.sparse")
