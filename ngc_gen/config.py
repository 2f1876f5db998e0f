"""Hydra/OmegaConf glue: the `ngc_root` resolver that anchors paths at the checkout."""
from __future__ import annotations

import os
from pathlib import Path

from omegaconf import OmegaConf


def repo_root() -> Path:
    """The checkout this package runs from (configs, shipped datasets, default caches);
    override with the NGC_ROOT environment variable."""
    return Path(os.environ.get("NGC_ROOT", Path(__file__).resolve().parents[1]))


def register_resolvers() -> None:
    if not OmegaConf.has_resolver("ngc_root"):
        OmegaConf.register_new_resolver("ngc_root", lambda: str(repo_root()))


register_resolvers()


def compose_config(config_name: str = "train", overrides: list[str] | None = None):
    """Compose the project's Hydra config outside `@hydra.main` (benchmarks, tests, notebooks);
    `run_dir` must then be given as an override, since there is no Hydra run directory."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(version_base="1.3", config_dir=str(repo_root() / "conf")):
        return compose(config_name=config_name, overrides=overrides or [])
