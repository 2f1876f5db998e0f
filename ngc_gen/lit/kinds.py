"""The one table of checkpoint kinds: the `hyper_parameters.checkpoint_kind` each training
stage's module records, and the run that writes it. Standard library only, so the entry points'
checks (`ngc_gen.lit.peek`, the stage registry) read it before torch loads."""
from __future__ import annotations

FIT = "ngc_gen.autodecoder"             # `train.py stage=fit` (lit/autodecoder.py, lit/fitted.py)
SHAPE_LATENT = "ngc_gen.shape_latent"   # `train.py stage=shape_latent` (lit/shape_latent.py)
DIFFUSION = "ngc_gen.diffusion"         # `train.py stage=diffusion` (lit/diffusion.py)

# kind -> the run that writes it, as an error message names it
KINDS = {FIT: "a `train.py stage=fit` run",
         SHAPE_LATENT: "a `train.py stage=shape_latent` run",
         DIFFUSION: "a `train.py stage=diffusion` run"}


def only(*kinds: str) -> dict[str, str]:
    """{kind: what it is} for the given kinds: the `kinds` argument of `peek.check_kind`."""
    return {k: KINDS[k] for k in kinds}
