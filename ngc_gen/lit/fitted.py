"""A fitting checkpoint for inference, without Lightning: the decoder and the codes of an
`AutoDecoder` (the same state_dict keys), its hyper-parameters readable as attributes.

edit.py, the editor, sample.py's writers and the stages that start from a fit only evaluate
the network; building the LightningModule would import Lightning (and torch._dynamo through
it), which was half of an edit's time at 128^3."""
from __future__ import annotations

import torch
from torch import nn

from . import kinds
from .parts import decoder_and_kind

CHECKPOINT_KIND = kinds.FIT  # the one table: ngc_gen/lit/kinds.py


class Hparams(dict):
    """A checkpoint's hyper-parameters: a dict whose keys read as attributes too."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


class FittedAutoDecoder(nn.Module):
    """decoder + codes of a fit (`hparams`: the checkpoint's `hyper_parameters`, with
    decoder (its config), kind, n_codes and meta); load the weights with `load_state_dict`."""

    def __init__(self, hparams: dict):
        super().__init__()
        self.hparams = Hparams(hparams)
        self.decoder, kind = decoder_and_kind(dict(hparams["decoder"]), hparams.get("kind"))
        self.hparams["kind"] = kind
        self.codes = nn.Embedding(int(hparams["n_codes"]), self.decoder.code_dim)

    @property
    def kind(self) -> str:
        return self.hparams.kind

    def sdf(self, ids: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        return self.decoder(self.codes(ids), coords)
