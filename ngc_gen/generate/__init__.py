"""Generation: decode shape latents to GCs + codes, sample new shapes with the latent diffusion,
interpolate and mix them, and write them as editable shapes (DESIGN.md section 5)."""
from .latents import latent_seed, lerp, slerp
from .model import ShapeGenerator, load_generator
from .modes import MODES, generate, interpolate, mix, run_sample
from .shapes import (DecodedShape, WrittenShape, decode_shapes, extract_decoded, mixed_sdf_fn,
                     normalise, write_edit_checkpoint, write_shape)

__all__ = ["DecodedShape", "MODES", "ShapeGenerator", "WrittenShape", "decode_shapes",
           "extract_decoded", "generate", "interpolate", "latent_seed", "lerp", "load_generator",
           "mix", "mixed_sdf_fn", "normalise", "run_sample", "slerp", "write_edit_checkpoint",
           "write_shape"]
