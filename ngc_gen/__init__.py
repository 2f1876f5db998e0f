"""ngc-gen: Neural Generalized Cylinders with EDM latent diffusion."""
