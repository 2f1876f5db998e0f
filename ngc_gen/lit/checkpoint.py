"""Loading trained LightningModules safely (weights_only) with a clear error for wrong files:
one loader for the fitting, shape-latent and diffusion checkpoints."""
from __future__ import annotations

import pickle
import re
from pathlib import Path

import torch

from ngc_gen.data.errors import DataError

from .fitted import CHECKPOINT_KIND, FittedAutoDecoder
from .peek import resolve_checkpoint  # noqa: F401  (torch-free; re-exported for its callers)

FIT_FIX = "pass the checkpoints/last.ckpt of a `train.py stage=fit` run"


def load_checkpoint_dict(path: Path, fix: str, map_location="cpu") -> dict:
    """torch.load(weights_only=True) with a DataError for files that are not checkpoints."""
    try:
        ckpt = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as e:
        blocked = re.search(r"GLOBAL (\S+)", str(e))
        if not blocked:  # not a pickle weights_only can read at all (text, truncated, other)
            raise DataError(f"{path} is not a loadable checkpoint (not a torch file)",
                            fix=fix) from None
        raise DataError(f"{path} holds pickled Python objects besides tensors and plain data"
                        f" ({blocked.group(1)}); it is refused "
                        "because loading it could run code from the file",
                        fix=f"{fix}; use checkpoints this project wrote, and never turn the "
                            "weights_only protection off for a file you did not make") from None
    except Exception as e:  # not a torch file (truncated, another format)
        raise DataError(f"{path} is not a loadable checkpoint ({type(e).__name__}: "
                        f"{str(e).splitlines()[0][:200]})", fix=fix) from None
    if not isinstance(ckpt, dict):
        raise DataError(f"{path} is not a Lightning checkpoint", fix=fix)
    return ckpt


def load_module(cls, path, kind: str, what: str, fix: str, map_location="cpu",
                whole: bool = False):
    """`cls` rebuilt from its saved hyper-parameters and weights, in eval mode; DataError if the
    file is missing, not a checkpoint, or a checkpoint of another kind (`what` names the one
    expected, e.g. "a diffusion checkpoint"). `whole`: `cls(hparams)` (one dict) instead of
    `cls(**hparams)`."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"checkpoint {path} does not exist", fix=fix)
    ckpt = load_checkpoint_dict(path, fix, map_location)
    hp = ckpt.get("hyper_parameters", {})
    if hp.get("checkpoint_kind") != kind:
        raise DataError(f"{path} is not {what} (kind {hp.get('checkpoint_kind')!r})", fix=fix)
    retired = getattr(cls, "RETIRED_HPARAMS", ())  # recorded by older versions, unused now
    hp = {k: v for k, v in hp.items() if k not in retired}
    try:
        module = cls(hp) if whole else cls(**hp)
        module.load_state_dict(ckpt["state_dict"])
    except (TypeError, ValueError, RuntimeError, KeyError) as e:  # hparams / weights of another
        raise DataError(f"{path} does not match this version's {cls.__name__} "  # version
                        f"({type(e).__name__}: {str(e).splitlines()[0][:200]})",
                        fix="retrain it with this version (`train.py`), or load it with the "
                            "version that wrote it") from None
    return module.eval()


def load_autodecoder(path, map_location="cpu") -> FittedAutoDecoder:
    """The decoder and codes of a Lightning checkpoint (`last.ckpt`, `best.ckpt`) of
    `stage=fit`, for inference: a `FittedAutoDecoder` (no Lightning import; the same weights,
    hyper-parameters and `sdf` as the AutoDecoder that was trained)."""
    return load_module(FittedAutoDecoder, path, CHECKPOINT_KIND,
                       "an NGC/DeepSDF fitting checkpoint", FIT_FIX, map_location, whole=True)
