"""The parts a LightningModule is built from: a network, a sub-network factory and an optimiser.

From a config they arrive built by Hydra (`_target_`; `_partial_: true` for a sub-network whose
input size is only known at run time, and for the optimiser, which the module gives its
parameters). From a checkpoint they arrive as the plain keyword dicts recorded in its
hyper-parameters. One rule turns either into a module and records the dict, so a checkpoint
loaded with weights_only=True rebuilds the module from plain data and never imports a class
path written in the file.
"""
from __future__ import annotations

from collections.abc import Mapping
from functools import partial

import torch
from torch import nn

from ngc_gen.models import DECODERS, build_decoder


def keywords(part, cls) -> dict:
    """The keyword arguments of `part` for `cls`: a dict (a checkpoint's record), a
    functools.partial of `cls` (a config with `_partial_: true`), or None (cls's defaults)."""
    if part is None:
        return {}
    if isinstance(part, partial):
        if part.func is not cls or part.args:
            raise TypeError(f"expected a partial of {cls.__name__} with keyword arguments only, "
                            f"got {part!r}")
        return dict(part.keywords)
    if isinstance(part, Mapping):
        return dict(part)
    raise TypeError(f"expected keyword arguments of {cls.__name__} (a dict or a partial), "
                    f"got {type(part).__name__}")


def decoder_and_kind(decoder, kind: str | None = None) -> tuple[nn.Module, str]:
    """(decoder module, its kind) from a built decoder (NGCDecoder / DeepSDFDecoder, from a
    config's `_target_`) or from a checkpoint's sizes dict plus `kind`."""
    if isinstance(decoder, nn.Module):
        found = getattr(decoder, "kind", None)
        if found not in DECODERS or not isinstance(decoder, DECODERS[found]):
            raise TypeError(f"decoder must be one of {sorted(DECODERS)}, got "
                            f"{type(decoder).__name__}")
        if kind is not None and kind != found:
            raise ValueError(f"kind {kind!r} contradicts the {found} decoder given")
        return decoder, found
    if kind is None:
        raise ValueError("a decoder given by its sizes needs its kind ('ngc' or 'deepsdf')")
    return build_decoder(kind, **dict(decoder)), kind


def optimizer_factory(optimizer):
    """The optimiser to build: the config's partial (`_partial_: true`), or Adam, which every
    config in conf/ names (a module loaded from a checkpoint is not trained through this)."""
    return optimizer if optimizer is not None else torch.optim.Adam
