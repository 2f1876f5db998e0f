"""The trained generative model: shape-latent module (+ latent diffusion when available).

`load_generator(run)` takes a diffusion run directory or checkpoint (it records its shape-latent
checkpoint), or a shape-latent run (training shapes only: interpolation and mixing between them,
no sampling). Shapes are named by training shape name (str) or generated index (int: shape i of
`sample_latents(seed)`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import torch

from ngc_gen.data.errors import DataError

from .latents import latent_seed

FIX = ("pass run=<dir> of a `train.py stage=diffusion` run (or of a `stage=shape_latent` run "
       "for interpolation / mixing between training shapes)")


@dataclass
class ShapeGenerator:
    shape_latent: object                 # ShapeLatentModule
    diffusion: object | None = None      # LatentDiffusion
    source: str = ""
    extra: dict = field(default_factory=dict)  # name -> latent (D,): reconstructed shapes

    def add_latents(self, path) -> list[str]:
        """Make the shapes of a latents file (`train.py stage=reconstruct` into this model's
        shape-latent run) resolvable by name; their latents must have this model's size."""
        from ngc_gen.lit.checkpoint import load_checkpoint_dict

        d = load_checkpoint_dict(Path(path), fix="pass latents=<reconstruct run>/latents.pt")
        z, names = d.get("latents"), d.get("names")
        dim = self.train_latents.shape[1]
        if not isinstance(z, torch.Tensor) or z.ndim != 2 or z.shape[1] != dim \
                or not isinstance(names, list) or len(names) != len(z):
            raise DataError(f"{path} does not hold named latents of size {dim} (this model's)",
                            field="latents", fix="pass the latents.pt of a `train.py "
                            "stage=reconstruct run=<this model's shape-latent run>` run")
        self.extra.update({str(n): v.float() for n, v in zip(names, z)})
        return [str(n) for n in names]

    @property
    def names(self) -> list[str]:
        return self.shape_latent.names

    @property
    def train_latents(self) -> torch.Tensor:
        return self.shape_latent.latents.weight.detach().float()

    @property
    def ngc(self):
        return self.shape_latent.ngc

    @property
    def frame(self) -> dict | None:
        """The body frame {up, front} the training collection was written in (None: not
        recorded); generated shapes are in it too."""
        return (self.shape_latent.hparams.meta or {}).get("frame")

    def _need_diffusion(self, what: str):
        if self.diffusion is None:
            raise DataError(f"{what} needs a diffusion model, but {self.source} is a shape-latent "
                            "run", fix="train one with `python train.py stage=diffusion "
                                       "shape_latent_run=<run>` and pass run=<that run>")

    @torch.no_grad()
    def sample_latents(self, indices, seed: int, steps: int = 18, churn: float = 0.0,
                       S_min: float = 0.0, S_max: float | None = None, S_noise: float = 1.0,
                       use_ema: bool = True, guide=None) -> torch.Tensor:
        """Latents (len(indices), D) of generated shapes `indices` under `seed`: shape i is the
        EDM sample from noise seeded by latent_seed(seed, i) (independent of the other shapes).
        guide: a denoiser wrapper for conditional sampling (LatentDiffusion.sample)."""
        self._need_diffusion("sampling new shapes")
        kw = dict(steps=int(steps), churn=float(churn), S_min=float(S_min),
                  S_max=float("inf") if S_max is None else float(S_max),
                  S_noise=float(S_noise), use_ema=bool(use_ema))
        out = [self.diffusion.sample(1, seed=latent_seed(seed, int(i)), guide=guide, **kw)[0]
               for i in indices]
        return torch.stack(out) if out else torch.zeros(0, self.train_latents.shape[1])

    @torch.no_grad()
    def noise_latents(self, n: int, seed: int, kind: str = "fitted") -> torch.Tensor:
        """Latents with no diffusion (the generation floor): `fitted` = N(mean, std^2) per
        dimension of the training latents; `standard` = N(0, I)."""
        z = self.train_latents
        g = torch.Generator().manual_seed(int(seed))
        eps = torch.randn(n, z.shape[1], generator=g)
        if kind == "standard":
            return eps
        if kind != "fitted":
            raise ValueError(f"noise kind must be 'fitted' or 'standard', got {kind!r}")
        return z.mean(0) + z.std(0) * eps

    def resolve(self, spec, seed: int, **sampler) -> tuple[str, torch.Tensor]:
        """(name, latent (D,)) of a training shape name or a generated index."""
        if isinstance(spec, str) and spec.strip().lstrip("-").isdigit():
            spec = int(spec)
        if isinstance(spec, int) and not isinstance(spec, bool):
            if spec < 0:
                raise DataError(f"generated shape index must be >= 0, got {spec}", field="a/b")
            self._need_diffusion(f"generated shape {spec}")
            return f"sample_{spec:03d}", self.sample_latents([spec], seed, **sampler)[0]
        if spec is None:
            raise DataError("no shape given", field="a/b",
                            fix="pass a training shape name or a generated shape index")
        if str(spec) in self.extra:
            return str(spec), self.extra[str(spec)].clone()
        names = self.names
        if str(spec) not in names:
            shown = ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")
            raise DataError(f"no training shape named {spec!r}", field="a/b",
                            fix=f"use a training shape name ({shown}) or an index of a "
                                f"generated shape (0, 1, ...)")
        i = names.index(str(spec))
        return str(spec), self.train_latents[i].clone()


def load_generator(run, shape_latent_run=None) -> ShapeGenerator:
    """A ShapeGenerator from a diffusion run (dir or checkpoint), or from a shape-latent run.
    `shape_latent_run` overrides the shape-latent checkpoint a diffusion run records."""
    from ngc_gen.lit.diffusion import CHECKPOINT_KIND as DIFFUSION
    from ngc_gen.lit.diffusion import LatentDiffusion
    from ngc_gen.lit.shape_latent import CHECKPOINT_KIND as SHAPE_LATENT
    from ngc_gen.lit.checkpoint import load_checkpoint_dict, resolve_checkpoint
    from ngc_gen.lit.shape_latent import ShapeLatentModule

    path = resolve_checkpoint(run, fix=FIX, what="run")
    kind = load_checkpoint_dict(path, fix=FIX).get("hyper_parameters", {}).get("checkpoint_kind")
    if kind == SHAPE_LATENT:
        return ShapeGenerator(ShapeLatentModule.from_checkpoint(path), None, str(path))
    if kind != DIFFUSION:
        raise DataError(f"{path} is neither a diffusion nor a shape-latent checkpoint (kind "
                        f"{kind!r})", fix=FIX)
    diffusion = LatentDiffusion.from_checkpoint(path)
    meta = diffusion.hparams.meta or {}
    sl_path = shape_latent_run or meta.get("shape_latent_checkpoint")
    if not sl_path:
        raise DataError(f"{path} does not record its shape-latent run",
                        fix="pass shape_latent_run=<dir or checkpoint>")
    try:
        shape_latent = ShapeLatentModule.from_checkpoint(sl_path)
    except DataError as e:
        raise DataError(f"the shape-latent run of diffusion checkpoint {path} cannot be loaded: "
                        f"{e}", fix="pass shape_latent_run=<dir or checkpoint> if it moved") from e
    dim = shape_latent.latents.weight.shape[1]
    if diffusion.hparams.dim != dim:
        raise DataError(f"diffusion latents have {diffusion.hparams.dim} dims, the shape-latent "
                        f"run {sl_path} has {dim}",
                        fix="pass the shape_latent_run the diffusion model was trained on")
    return ShapeGenerator(shape_latent, diffusion, str(Path(path)))
