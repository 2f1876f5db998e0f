"""The diffusion settings' allowed values, torch-free so that train.py checks them before the
heavy imports (ngc_gen.app.stages.registry) from the same home the module validates them with."""

STANDARDISE = ("per_dim", "scalar", "none", "pca")   # diffusion.standardise
PCA_COMPLETE = ("mean", "nearest")                     # diffusion.pca_complete
