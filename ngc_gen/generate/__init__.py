"""Generation: decode shape latents to GCs + codes, sample new shapes with the latent diffusion,
interpolate and mix them (DESIGN.md section 5). Writing them as editable shapes on disk is
sample.py's runner (ngc_gen.app.sample)."""
from .latents import latent_path, latent_seed, lerp, slerp
from .model import ShapeGenerator, load_generator
from .shapes import (DecodedShape, WrittenShape, decode_shapes, extract_decoded, mixed_sdf_fn,
                     normalise, write_edit_checkpoint, write_shape)

__all__ = ["DecodedShape", "ShapeGenerator", "WrittenShape", "decode_shapes", "extract_decoded",
           "latent_path", "latent_seed", "lerp", "load_generator", "mixed_sdf_fn", "normalise",
           "slerp", "write_edit_checkpoint", "write_shape"]
