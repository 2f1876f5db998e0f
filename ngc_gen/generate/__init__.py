"""Generation: decode shape latents to GCs + codes, sample new shapes with the latent diffusion,
interpolate and mix them, and write them as editable shapes (DESIGN.md section 5)."""
from .latents import latent_seed, lerp, slerp
from .model import ShapeGenerator, load_generator
from .modes import MODES, generate, interpolate, mix, run_sample
from .shapes import (WrittenShape, auto_chunk, decode_shapes, normalise, write_edit_checkpoint,
                     write_shape)

__all__ = ["MODES", "ShapeGenerator", "WrittenShape", "auto_chunk", "decode_shapes", "generate",
           "interpolate", "latent_seed", "lerp", "load_generator", "mix", "normalise",
           "run_sample", "slerp", "write_edit_checkpoint", "write_shape"]
