"""Part mixing (paper Sec. 3.2, Fig. 11): blend one GC's features with another's along t.

A blend weight w(t) in [0, 1] over normalised arc length says how much of part B replaces part A
at each cross-section: f(t) = (1 - w(t)) f_A(t) + w(t) f_B(t). The paper blends with a truncated
linear ramp over [t0, t1]; smoothstep gives a C1 seam. Where regions of different GCs overlap,
The smooth union of SDFs (`smooth_min`) lives in `ngc_gen.geometry.smooth`.

Weights are small frozen callables (t tensor -> same-shape tensor), so an edit program can name
one (`blend_weight("truncated_linear", t0=0.3, t1=0.6)`) and its repr says what it is.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from ngc_gen.shape.features import blend_features  # noqa: F401  (re-exported)

from .errors import EditError


def _as_tensor(t) -> torch.Tensor:
    t = torch.as_tensor(t)
    return t if t.is_floating_point() else t.to(torch.get_default_dtype())


def _check_range(name: str, t0, t1) -> tuple[float, float]:
    try:
        t0, t1 = float(t0), float(t1)
    except (TypeError, ValueError):
        raise EditError(f"t0, t1 must be numbers, got {t0!r}, {t1!r}", op=name,
                        field="t0, t1") from None
    if not (0.0 <= t0 < t1 <= 1.0):  # also rejects NaN
        raise EditError(f"needs 0 <= t0 < t1 <= 1, got t0 = {t0}, t1 = {t1}", op=name,
                        field="t0, t1",
                        fix="give a non-empty range inside [0, 1] (constant(1) replaces a part "
                            "outright)")
    return t0, t1


@dataclass(frozen=True)
class Linear:
    """w(t) = t on [0, 1] (clamped outside): A at the start, B at the end."""

    def __call__(self, t):
        return _as_tensor(t).clamp(0.0, 1.0)


@dataclass(frozen=True)
class TruncatedLinear:
    """w = 0 before t0, 1 after t1, linear in between (the paper's choice)."""

    t0: float
    t1: float

    def __post_init__(self):
        _check_range("truncated_linear", self.t0, self.t1)

    def __call__(self, t):
        return ((_as_tensor(t) - self.t0) / (self.t1 - self.t0)).clamp(0.0, 1.0)


@dataclass(frozen=True)
class Smoothstep:
    """w = x^2 (3 - 2x), x the truncated-linear ramp over [t0, t1]: C1, zero slope at both ends."""

    t0: float
    t1: float

    def __post_init__(self):
        _check_range("smoothstep", self.t0, self.t1)

    def __call__(self, t):
        x = ((_as_tensor(t) - self.t0) / (self.t1 - self.t0)).clamp(0.0, 1.0)
        return x * x * (3.0 - 2.0 * x)


@dataclass(frozen=True)
class Constant:
    """w(t) = w everywhere: 0 keeps A, 1 replaces it by B, 0.5 averages."""

    w: float

    def __post_init__(self):
        if not (0.0 <= float(self.w) <= 1.0):
            raise EditError(f"weight must lie in [0, 1], got {self.w}", op="constant",
                            field="w")

    def __call__(self, t):
        return torch.full_like(_as_tensor(t), float(self.w))


def linear() -> Linear:
    return Linear()


def truncated_linear(t0: float, t1: float) -> TruncatedLinear:
    return TruncatedLinear(*_check_range("truncated_linear", t0, t1))


def smoothstep(t0: float, t1: float) -> Smoothstep:
    return Smoothstep(*_check_range("smoothstep", t0, t1))


def constant(w: float) -> Constant:
    try:
        return Constant(float(w))
    except (TypeError, ValueError):
        raise EditError(f"weight must be a number in [0, 1], got {w!r}", op="constant",
                        field="w") from None


BLENDS = {"linear": linear, "truncated_linear": truncated_linear, "smoothstep": smoothstep,
          "constant": constant}


def blend_weight(name: str, **params):
    """A weight function by name (a key of BLENDS) and its parameters, as edit programs give."""
    if name not in BLENDS:
        raise EditError(f"unknown blend; use one of {sorted(BLENDS)}", op="mix", field="blend",
                        value=name)
    try:
        return BLENDS[name](**params)
    except TypeError as e:
        raise EditError(f"bad parameters {sorted(params)} for blend '{name}' ({e})",
                        op="mix", field="blend") from None


#: the parameters each mix blend takes (one table for edit programs and sample.py mode=mix)
BLEND_PARAMS = {"replace": (), "constant": ("w",), "linear": (), "truncated_linear": ("t0", "t1"),
                "smoothstep": ("t0", "t1")}


def mix_weight(blend: str = "replace", op: str = "mix", **params):
    """The weight function of a part mix: None for "replace" (exactly part B's features), else
    `blend_weight(blend, **params)`; EditError naming what is missing or unexpected."""
    if blend not in BLEND_PARAMS:
        raise EditError(f"unknown blend; use one of {sorted(BLEND_PARAMS)}", op=op,
                        field="blend", value=blend)
    need = list(BLEND_PARAMS[blend])
    missing, extra = [k for k in need if k not in params], sorted(set(params) - set(need))
    if missing or extra:
        raise EditError(f"blend '{blend}' takes {need or 'no parameters'}"
                        + (f"; missing {missing}" if missing else "")
                        + (f"; unexpected {extra}" if extra else ""), op=op, field="blend")
    return None if blend == "replace" else blend_weight(blend, **params)
