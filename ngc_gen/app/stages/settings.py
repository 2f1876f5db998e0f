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
    """`value` by the project's number rule; ConfigError naming `group.key` (`key` for a
    top-level key: group "")."""
    try:
        return read_number(value, **rule)
    except NumberError as e:
        name = f"{group}.{key}" if group else key
        raise ConfigError(e.what, key=name, value=value, fix=e.config_fix(name)) from None


def _choice(group: str, key: str, value, allowed: tuple[str, ...]) -> str:
    name = f"{group}.{key}" if group else key
    if value not in allowed:
        raise ConfigError(f"must be {' or '.join(allowed)}", key=name, value=value,
                          fix=f"pass {name}={allowed[0]} (or {', '.join(allowed[1:])})")
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


# ---- sample.py's modes: the keys of conf/mode/<mode>.yaml (top-level keys of sample.py's
# config, so a user types `n=8`, `steps=12`); `mode_settings` builds the one the config names
@dataclass(frozen=True)
class GenerateSettings:
    """mode=generate: n new shapes."""

    n: int

    def __post_init__(self):
        object.__setattr__(self, "n", _number("", "n", self.n, integer=True, minimum=1))


@dataclass(frozen=True)
class InterpolateSettings:
    """mode=interpolate: `steps` shapes from a to b (both ends included), lerp or slerp."""

    a: int | str
    b: int | str
    steps: int
    interp: str

    def __post_init__(self):
        object.__setattr__(self, "steps",
                           _number("", "steps", self.steps, integer=True, minimum=2))
        _choice("", "interp", self.interp, ("lerp", "slerp"))


@dataclass(frozen=True)
class MixSettings:
    """mode=mix: a with b's `part`; the blend and its parameters (t0, t1, w: null when the blend
    does not read them)."""

    a: int | str
    b: int | str
    part: str
    geometry: str
    blend: str
    t0: float | None
    t1: float | None
    w: float | None

    def __post_init__(self):
        for key in ("t0", "t1", "w"):
            if getattr(self, key) is not None:
                object.__setattr__(self, key, _number("", key, getattr(self, key)))
        _choice("", "geometry", self.geometry, ("source", "target"))


@dataclass(frozen=True)
class ConditionSettings:
    """mode=condition: n shapes guided toward the GCs of the file `gcs` (`condition`: strength,
    project_steps, replace)."""

    n: int
    gcs: str | None
    condition: dict

    def __post_init__(self):
        object.__setattr__(self, "n", _number("", "n", self.n, integer=True, minimum=1))
        c = dict(self.condition)
        c["strength"] = _number("condition", "strength", c.get("strength"), minimum=0)
        c["project_steps"] = _number("condition", "project_steps", c.get("project_steps"),
                                     integer=True, minimum=0)
        object.__setattr__(self, "condition", c)


MODES = {"generate": GenerateSettings, "interpolate": InterpolateSettings, "mix": MixSettings,
         "condition": ConditionSettings}


def mode_settings(cfg):
    """The settings of the mode sample.py's config names, from its keys (conf/mode/<mode>.yaml:
    their one source); ConfigError naming the key of a bad value, or an unknown mode."""
    import dataclasses

    from omegaconf import OmegaConf

    mode = cfg.get("mode")
    if mode not in MODES:
        raise ConfigError("unknown mode", key="mode", value=mode,
                          fix=f"use one of mode={' | mode='.join(MODES)}")
    fields = [f.name for f in dataclasses.fields(MODES[mode])]
    values = OmegaConf.to_container(cfg, resolve=True)
    return MODES[mode](**{k: values.get(k) for k in fields})
