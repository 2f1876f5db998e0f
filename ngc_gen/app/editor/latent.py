"""Shapes from a generation run for the editor: sample one from a seed, or blend two latents.

Each new shape goes into the session's `ShapeLibrary` (so it can be opened, mixed from and
saved), decoded by the run's shape decoder with its GCs, which the editor then edits like a
fitted shape's.
"""
from __future__ import annotations

import torch

from ngc_gen.generate import decode_shapes, lerp
from ngc_gen.shape import Shape

from .library import ShapeLibrary


class LatentShapes:
    """generator: a `ngc_gen.generate.ShapeGenerator`; library: where new shapes go."""

    def __init__(self, generator, library: ShapeLibrary):
        self.generator, self.library = generator, library

    @property
    def can_sample(self) -> bool:
        return self.generator.diffusion is not None

    def _decode(self, latent: torch.Tensor, name: str) -> Shape:
        shape = decode_shapes(self.generator.shape_latent, latent[None], [name])[0]
        return self.library.add(shape)

    def training(self, name: str | None = None) -> Shape:
        """A training shape of the run (default the first) decoded from its latent."""
        spec = name if name is not None else self.generator.names[0]
        name, z = self.generator.resolve(spec, 0)
        return self._decode(z, name)

    def sample(self, seed: int) -> Shape:
        """The diffusion model's shape for `seed` (shape 0 of `sample.py seed=<seed>`)."""
        z = self.generator.sample_latents([0], int(seed))[0]
        return self._decode(z, f"sample_s{int(seed)}")

    def interpolate(self, a: str, b: str, alpha: float, seed: int) -> Shape:
        """(1 - alpha) z_A + alpha z_B, A and B training shape names or generated indices under
        `seed` (as sample.py's a= / b=)."""
        name_a, za = self.generator.resolve(a, int(seed))
        name_b, zb = self.generator.resolve(b, int(seed))
        z = lerp(za, zb, torch.tensor([float(alpha)]))[0]
        return self._decode(z, f"lerp_{name_a}_{name_b}_{float(alpha):.2f}")
