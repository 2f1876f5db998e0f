"""GC edits of the training shapes as extra training latents for the diffusion: a small
collection's recipe (docs/generation.md, "Small collections").

A shape's GCs are explicit, so a training shape with a leg swung, a neck stretched or a head
made thicker is a new shape at no meshing cost: its latent is the edited GC parameters (in the
decoder's std units) with the shape's own free entries, from which the decoder makes the codes.
With 8 training shapes the EDM learns 8 points and draws them again; with each shape's edits it
learns a neighbourhood around each, and between them.

`edited_latents` draws `copies` edits of every training shape, each of every GC at once:
- swing: every GC but the root turns about its start by an angle in [-swing, swing] degrees
  about a random axis normal to its chord; the GCs attached to it turn with it (a GC much
  shorter than the root, an ear, only turns with its parent);
- stretch: every GC's control points scale about its start by a factor in `stretch`; the GCs
  attached to it move with the point they sit at;
- scale: every GC's radii by a factor in `scale`; twist: every key's twist by an angle in
  [-twist, twist] degrees.
`transferred_latents` moves every shape by each other shape's pose as that shape differs from the
collection's mean (`pose_transfer.PoseTransfer` with the mean as the shared pose): a mesh's
limbs take another mesh's limb directions. All arrays are batched over shapes (leading N).
"""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.data.errors import DataError

from .pose_transfer import PoseTransfer


def _random_rotations(axes_normal_to: np.ndarray, degrees: np.ndarray,
                      rng: np.random.Generator) -> np.ndarray:
    """(N, 3) chords, (N,) angles -> (N, 3, 3) rotations about random axes normal to the chords."""
    from scipy.spatial.transform import Rotation

    c = axes_normal_to / np.maximum(np.linalg.norm(axes_normal_to, axis=1, keepdims=True), 1e-12)
    v = rng.normal(size=c.shape)
    v -= (v * c).sum(1, keepdims=True) * c
    v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    return Rotation.from_rotvec(v * np.radians(degrees)[:, None]).as_matrix()


def edit_parameters(theta: np.ndarray, pt: PoseTransfer, rng: np.random.Generator,
                    swing: float, stretch, scale, twist: float,
                    swing_min_length: float) -> np.ndarray:
    """(N, P) raw GC parameters -> (N, P) each randomly edited (module docstring); `pt` gives
    the template's layout and parent tree. A GC whose chord is shorter than
    `swing_min_length` times the root's (an ear, an antler) only follows its parent: swung
    about its start it sinks into the part it sits on."""
    theta = np.asarray(theta, np.float64)
    out, n = theta.copy(), len(theta)
    rows = np.arange(n)
    root = pt.points(theta, pt.root)
    root_len = np.linalg.norm(root[:, -1] - root[:, 0], axis=1)
    moved = {}   # GC -> (old points, new points): where its children's starts go
    turn = {}    # GC -> (N, 3, 3) rotation its children inherit
    for g in pt.order:
        P = pt.points(theta, g)
        if g == pt.root:
            Rg, start = np.broadcast_to(np.eye(3), (n, 3, 3)), P[:, 0]
        else:
            par = pt.parents[g]
            old_par, new_par = moved[par]
            k = ((old_par - P[:, :1]) ** 2).sum(-1).argmin(1)       # the point it sits at
            start = new_par[rows, k] + np.einsum("nij,nj->ni", turn[par],
                                                 P[:, 0] - old_par[rows, k])
            long = np.linalg.norm(P[:, -1] - P[:, 0], axis=1) >= swing_min_length * root_len
            own = _random_rotations(P[:, -1] - P[:, 0],
                                    rng.uniform(-swing, swing, n) * long, rng)
            Rg = own @ turn[par]
        f = rng.uniform(stretch[0], stretch[1], n)[:, None, None]
        new = start[:, None] + f * np.einsum("nij,nmj->nmi", Rg, P - P[:, :1])
        moved[g], turn[g] = (P, new), Rg
        out[:, pt.slice[(g, "points")]] = new.reshape(n, -1)
        s = pt.slice[(g, "log_radii")]
        out[:, s] += np.log(rng.uniform(scale[0], scale[1], n))[:, None]
        out[:, pt.slice[(g, "twist")]] += rng.uniform(-twist, twist, (n, 1)) if twist else 0.0
    return out


def _latents(shape_latent, theta: np.ndarray, sources: np.ndarray) -> torch.Tensor:
    """Latents of raw parameters `theta` (T, P) with the free entries of training shapes
    `sources` (T,)."""
    sd = shape_latent.shape_decoder
    z = sd.gc_part(sd.normalise(torch.as_tensor(theta).to(sd.param_mean))).clamp(-sd.bound,
                                                                                    sd.bound)
    free = shape_latent.latents.weight.detach()[torch.as_tensor(sources), sd.n_params:]
    return torch.cat([z.float(), free.float()], 1)


def _pose_transfer(shape_latent, parents: dict) -> PoseTransfer:
    if not shape_latent.shape_decoder.explicit:
        raise DataError("augmenting by GC edits needs explicit latents (shape_latent."
                        "shape_decoder.explicit=true, the default)", field="diffusion.augment")
    return PoseTransfer(shape_latent.template, parents)


def edited_latents(shape_latent, parents: dict, copies: int, seed: int,
                   **ranges) -> torch.Tensor:
    """`copies` random GC edits of every training shape (`edit_parameters`'s ranges) as
    latents (copies * N, D) float."""
    pt = _pose_transfer(shape_latent, parents)
    theta = shape_latent.target_params.double().cpu().numpy()
    rng = np.random.default_rng(seed)
    sources = np.tile(np.arange(len(theta)), int(copies))
    return _latents(shape_latent, edit_parameters(theta[sources], pt, rng, **ranges), sources)


def transferred_latents(shape_latent, parents: dict) -> torch.Tensor:
    """Every training shape A moved as each other shape B differs from the collection's mean
    parameters (A's free entries): (N (N - 1), D) float."""
    pt = _pose_transfer(shape_latent, parents)
    theta = shape_latent.target_params.double().cpu().numpy()
    n = len(theta)
    a, b = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    keep = a != b
    a, b = a[keep], b[keep]
    mean = np.broadcast_to(theta.mean(0), (len(a), theta.shape[1]))
    return _latents(shape_latent, pt(theta[a], mean, theta[b]), a)
