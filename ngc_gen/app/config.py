"""Hydra/OmegaConf glue: the `ngc_root` resolver that anchors paths at the checkout."""
from __future__ import annotations

import os
from pathlib import Path

from omegaconf import OmegaConf


def repo_root() -> Path:
    """The checkout this package runs from (configs, shipped datasets, default caches);
    override with the NGC_ROOT environment variable."""
    return Path(os.environ.get("NGC_ROOT", Path(__file__).resolve().parents[2]))


def register_resolvers() -> None:
    """Register the project's OmegaConf resolvers (`ngc_root`); process-wide state, so called by
    the entry points before Hydra composes and by `compose_config`, never at import time."""
    if not OmegaConf.has_resolver("ngc_root"):
        OmegaConf.register_new_resolver("ngc_root", lambda: str(repo_root()))


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
        with initialize_config_dir(version_base="1.3", config_dir=str(repo_root() / "conf")):
            return compose(config_name=config_name, overrides=overrides or [])
    finally:
        if running is not None:
            GlobalHydra.instance().hydra = running
