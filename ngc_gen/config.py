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
