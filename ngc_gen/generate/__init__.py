"""Generation: decode shape latents to GCs + codes, sample new shapes with the latent diffusion,
interpolate and mix them (docs/generation.md). Writing them as editable shapes on disk is
sample.py's runner (ngc_gen.app.stages.sample)."""
from .latents import latent_path, latent_seed, lerp, slerp
from .model import ShapeGenerator, load_generator
from .shapes import (WrittenShape, auto_chunk, decode_shapes, normalise, write_edit_checkpoint,
                     write_shape)

__all__ = ["ShapeGenerator", "WrittenShape", "auto_chunk", "decode_shapes", "latent_path",
           "latent_seed", "lerp", "load_generator", "normalise", "slerp", "write_edit_checkpoint",
           "write_shape"]
