"""nn.Modules: NGC decoder, DeepSDF baseline, EDM preconditioning/denoiser and sampler."""
from .deepsdf import DeepSDFDecoder
from .edm import EDMLoss, EDMPrecond, FourierEmbedding, ResidualMLPDenoiser
from .encoding import PositionalEncoding
from .ngc import NGCDecoder
from .sampler import edm_sampler, edm_sigma_steps

DECODERS = {"ngc": NGCDecoder, "deepsdf": DeepSDFDecoder}


def build_decoder(kind: str, **sizes):
    """A decoder by kind ('ngc' | 'deepsdf') from its sizes: how a checkpoint's record is rebuilt
    (configs build decoders by `_target_`; the sizes live in conf/model/*.yaml)."""
    if kind not in DECODERS:
        raise ValueError(f"unknown model kind {kind!r}; choose one of {sorted(DECODERS)}")
    return DECODERS[kind](**sizes)


__all__ = ["DECODERS", "DeepSDFDecoder", "EDMLoss", "EDMPrecond", "FourierEmbedding",
           "NGCDecoder", "PositionalEncoding", "ResidualMLPDenoiser", "build_decoder",
           "edm_sampler", "edm_sigma_steps"]
