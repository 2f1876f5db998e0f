"""nn.Modules: NGC decoder, DeepSDF baseline, EDM preconditioning/denoiser and sampler."""
from .deepsdf import DeepSDFDecoder
from .edm import EDMLoss, EDMPrecond, FourierEmbedding, ResidualMLPDenoiser
from .sampler import edm_sampler, edm_sigma_steps
from .encoding import PositionalEncoding
from .ngc import NGCConfig, NGCDecoder

DECODERS = {"ngc": NGCDecoder, "deepsdf": DeepSDFDecoder}


def build_decoder(kind: str, preset: str | None = None, **config):
    """A decoder by kind ('ngc' | 'deepsdf') from a preset name and/or explicit sizes."""
    if kind not in DECODERS:
        raise ValueError(f"unknown model kind {kind!r}; choose one of {sorted(DECODERS)}")
    cls = DECODERS[kind]
    if preset is not None:
        if preset not in cls.presets():
            raise ValueError(f"unknown {kind} preset {preset!r}; choose one of "
                             f"{sorted(cls.presets())}")
        config = {**cls.presets()[preset], **config}
    return cls(**config)


__all__ = ["DECODERS", "EDMLoss", "EDMPrecond", "FourierEmbedding", "ResidualMLPDenoiser",
           "build_decoder", "edm_sampler", "edm_sigma_steps", "DeepSDFDecoder", "NGCConfig", "NGCDecoder", "PositionalEncoding"]
