"""The settings of the stages whose config group is built by `_target_`, as dataclasses with no
defaults of their own: the group's YAML (conf/<group>/default.yaml) is the one source of every
value, and a key the dataclass does not know is an error. Light (standard library and the
project's number rule), so the entry point builds them before torch loads and a bad value fails
in a second with the key to change."""
from __future__ import annotations

from dataclasses import dataclass

from ngc_gen.values import NumberError, read_number

from ..runtime.errors import ConfigError


def _number(group: str, key: str, value, **rule):
    try:
        return read_number(value, **rule)
    except NumberError as e:
        name = f"{group}.{key}"
        raise ConfigError(e.what, key=name, value=value, fix=e.config_fix(name)) from None


def _choice(group: str, key: str, value, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise ConfigError(f"must be {' or '.join(allowed)}", key=f"{group}.{key}", value=value,
                          fix=f"pass {group}.{key}={allowed[0]} (or {', '.join(allowed[1:])})")
    return value


@dataclass(frozen=True)
class ReconstructSettings:
    """`train.py stage=reconstruct` (conf/reconstruct/default.yaml, where the meaning of each
    field is written): optimisation steps and learning rates of the codes or latents, the GCs
    the reconstruction is meshed with, and the code refinement after a latent fit."""

    max_steps: int
    code_lr: float
    latent_lr: float
    param_weight: float | None
    gcs: str
    refine_steps: int

    def __post_init__(self):
        g = "reconstruct"
        for key, rule in (("max_steps", dict(integer=True, minimum=1)),
                          ("code_lr", dict(minimum=0, strict_minimum=True)),
                          ("latent_lr", dict(minimum=0, strict_minimum=True)),
                          ("refine_steps", dict(integer=True, minimum=0))):
            object.__setattr__(self, key, _number(g, key, getattr(self, key), **rule))
        if self.param_weight is not None:
            object.__setattr__(self, "param_weight",
                               _number(g, "param_weight", self.param_weight, minimum=0))
        _choice(g, "gcs", self.gcs, ("input", "decoded"))
