"""Reconstruction: put new shapes into a trained model by optimising only their codes (an NGC /
DeepSDF fit) or their shape latents (a shape-latent model), every network weight frozen
(DeepSDF's `reconstruct`). The modules built here train with the usual Lightning loop; their
checkpoints have the format of the model they came from, so edit.py and sample.py take them.
"""
from __future__ import annotations

import torch

from .autodecoder import AutoDecoder
from .shape_latent import ShapeLatentModule


def codes_only_autodecoder(fit: AutoDecoder, n_codes: int, meta: dict, code_lr: float,
                           code_init_std: float | None = None) -> AutoDecoder:
    """A new AutoDecoder with `fit`'s decoder (weights copied, frozen: lr 0 from step 0 and no
    gradients) and `n_codes` fresh codes to fit; loss settings (clamp, code_reg) as in `fit`."""
    hp = fit.hparams
    module = AutoDecoder(kind=hp.kind, decoder=dict(hp.decoder), n_codes=int(n_codes), lr=0.0,
                         code_lr=float(code_lr), code_reg=hp.code_reg, clamp=hp.clamp,
                         codes_only_from=0.0,
                         code_init_std=hp.code_init_std if code_init_std is None
                         else float(code_init_std), meta=meta)
    module.decoder.load_state_dict(fit.decoder.state_dict())
    module.decoder.requires_grad_(False)
    return module


def latent_only_module(trained: ShapeLatentModule, vectors, meta: dict, latent_lr: float,
                       param_weight: float | None = None) -> ShapeLatentModule:
    """A new ShapeLatentModule with `trained`'s shape decoder and NGC decoder (weights and the
    decoder's parameter statistics copied, frozen) and one fresh latent per row of `vectors`
    (the new shapes' annotated GC parameters, in the trained template). No latent noise: the
    latent is fitted to the shape itself."""
    hp = dict(trained.hparams)
    for k in ("n_shapes", "meta", "latent_noise", "lr", "latent_lr", "checkpoint_kind"):
        hp.pop(k, None)
    if param_weight is not None:
        hp["param_weight"] = float(param_weight)
    vectors = torch.as_tensor(vectors, dtype=torch.float64)
    module = ShapeLatentModule(n_shapes=len(vectors), meta=meta, latent_noise=0.0, lr=0.0,
                               latent_lr=float(latent_lr), **hp)
    module.set_targets(vectors)  # sets the decoder's statistics from these shapes: restored below
    module.ngc.load_state_dict(trained.ngc.state_dict())
    module.shape_decoder.load_state_dict(trained.shape_decoder.state_dict())
    module.ngc.requires_grad_(False)
    module.shape_decoder.requires_grad_(False)
    with torch.no_grad():  # start from the mean training latent: a shape the decoder knows
        module.latents.weight.copy_(trained.latents.weight.mean(0).expand_as(module.latents.weight))
    module.write_gc_entries()  # explicit latents: the new shapes' own GCs, in trained units
    return module


def refine_codes_module(trained: ShapeLatentModule, latents: torch.Tensor, meta: dict,
                        code_lr: float) -> AutoDecoder:
    """Codes-only AutoDecoder on `trained`'s NGC decoder (frozen) whose codes start at the ones
    `latents` (N, D) decode to, in the fit's code order (shape i, GC k -> code i K + k). It
    fits what the latent space cannot express; the latents stay as they are."""
    hp = trained.hparams
    with torch.no_grad():
        _, codes = trained.decode(latents)
    module = AutoDecoder(kind="ngc", decoder=dict(trained.ngc.config),
                         n_codes=codes.shape[0] * codes.shape[1], lr=0.0, code_lr=float(code_lr),
                         code_reg=0.0, clamp=hp.clamp, codes_only_from=0.0, meta=meta)
    module.decoder.load_state_dict(trained.ngc.state_dict())
    module.decoder.requires_grad_(False)
    with torch.no_grad():
        module.codes.weight.copy_(codes.reshape(-1, codes.shape[-1]))
    return module
