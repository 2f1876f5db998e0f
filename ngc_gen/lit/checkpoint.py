"""Loading trained auto-decoders safely (weights_only) with a clear error for wrong files."""
from __future__ import annotations

from pathlib import Path

import torch

from ngc_gen.data.errors import DataError

from .autodecoder import CHECKPOINT_KIND, AutoDecoder


def load_autodecoder(path, map_location="cpu") -> AutoDecoder:
    """An AutoDecoder from a Lightning checkpoint (`last.ckpt`, `best.ckpt`) of `stage=fit`."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"checkpoint {path} does not exist",
                        fix="pass the checkpoints/last.ckpt of a `train.py stage=fit` run")
    try:
        ckpt = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as e:  # not a torch file, or one holding arbitrary pickled objects
        raise DataError(f"{path} is not a loadable checkpoint ({type(e).__name__}: "
                        f"{str(e).splitlines()[0][:200]})",
                        fix="pass the checkpoints/last.ckpt of a `train.py stage=fit` run") from None
    hp = ckpt.get("hyper_parameters", {}) if isinstance(ckpt, dict) else {}
    if hp.get("checkpoint_kind") != CHECKPOINT_KIND:
        raise DataError(f"{path} is not an NGC/DeepSDF fitting checkpoint (kind "
                        f"{hp.get('checkpoint_kind')!r})",
                        fix="pass the checkpoints/last.ckpt of a `train.py stage=fit` run")
    module = AutoDecoder(**hp)
    module.load_state_dict(ckpt["state_dict"])
    return module.eval()
