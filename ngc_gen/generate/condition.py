"""Generation from a skeleton (docs/generation.md): sample shapes whose decoded GCs match
target GCs given for some or all of the template's GCs.

A condition fixes the parameters theta* of a subset of GCs (control points, log key radii, key
twists, log caps: `GCTemplate` layout). The shape decoder maps a latent to its parameters in
std units z(s) (`ShapeDecoder`), so the residual of a latent is, over the conditioned
parameters that vary in the training data,

    r(s) = z(s) - z*,          z* = (theta* - mean) / std,     gc error = rms(r)  (std units)

Guidance (reconstruction guidance on the denoised estimate, in the EDM symbols): at every
sampler evaluation the denoised estimate D(x; sigma) (standardised latents, sigma_data = 1) is
replaced by the posterior mean of the clean latent given x AND the condition, for a decoder
linearised at D, a clean latent ~ N(D, c_out(sigma)^2 I) given x, and GC parameters observed
with noise std 1/w (std units):

    D~(x; sigma) = D - (J^T J + (w c_out(sigma))^-2 I)^-1 J^T r(D),     J = dr/dD

w = `strength` is the precision of the condition: 0 is the unconditional sampler bit for bit;
with explicit latents (z(s) = the latent's GC entries, J a selection) held-out creatures' GCs are
met to 0.17 std at 10 and 0.067 at 30 (the default; bench/condition.py --sweep). The step is
the smallest latent change that removes
the residual where the condition constrains the latent (J large against 1/(w c_out)); latent
directions it does not constrain keep what the diffusion model sampled (the other GCs, surface
detail). c_out -> sigma at low noise, so the correction fades as the sample settles;
`project_steps` more steps with scale 1 on the final latent (decoder only) remove what is left
(at the cost of diversity: bench/condition.py --sweep measures both).

"Replace GCs" (`replace_gcs`): the output takes the conditioned GCs verbatim (the user's
drawing, including its `up`) and keeps the sampled codes and the other decoded GCs.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import yaml

from ngc_gen.data.annotations import _parse_gc as parse_gc  # the data layer's GC validation
from ngc_gen.data.annotations import similar_gc_dict
from ngc_gen.data.errors import DataError
from ngc_gen.models.shape_decoder import GCTemplate, gc_vector


@dataclass(frozen=True)
class GCCondition:
    """Target GCs for a subset of a template: names and canonical GC dicts (template order),
    target theta (P,) float64 (0 outside the mask), mask (P,) bool of conditioned parameters."""

    names: tuple[str, ...]
    gcs: tuple[dict, ...]
    target: torch.Tensor
    mask: torch.Tensor
    source: str | None = None

    def __len__(self) -> int:
        return len(self.names)


def condition_from_gcs(template: GCTemplate, gcs, source=None) -> GCCondition:
    """Validate GC dicts (annotation format) against `template` and build the condition.

    DataError (naming the file, GC and field) for: a GC name not in the template, a name given
    twice, a curve that is not a Bezier of the template's degree, keys at other t's, a stretched
    (reparameterised) GC, non-finite or otherwise invalid values."""
    if not isinstance(gcs, list) or not gcs:
        raise DataError(f"a condition needs a non-empty list of GCs, got {gcs!r}"[:200],
                        path=source, field="gcs",
                        fix="write 'gcs: [...]' with the GCs to keep (annotation format)")
    slots = {s.name: (k, s) for k, s in enumerate(template.slots)}
    chosen = {}
    for i, d in enumerate(gcs):
        gc = parse_gc(d, i, source)                 # structure, numbers, finiteness, geometry
        if gc.name not in slots:
            raise DataError(f"no GC named {gc.name!r} in the template", path=source, gc=gc.name,
                            field="name", fix=f"use names of the template: {template.names}")
        if gc.name in chosen:
            raise DataError("GC given twice", path=source, gc=gc.name, field="name",
                            fix="give each GC of the condition once")
        k, slot = slots[gc.name]
        if d["curve"].get("type") != "bezier":
            raise DataError(f"curve type {d['curve'].get('type')!r}, the template's GCs are "
                            "Bezier curves", path=source, gc=gc.name, field="curve.type",
                            fix=f"give a Bezier curve with {slot.degree + 1} control points")
        degree = len(d["curve"]["points"]) - 1
        if degree != slot.degree:
            raise DataError(f"curve degree {degree} ({degree + 1} control points), the "
                            f"template's is {slot.degree}", path=source, gc=gc.name,
                            field="curve.points", fix=f"give {slot.degree + 1} control points")
        ts = [k_.t for k_ in gc.keys]
        if len(ts) != len(slot.key_ts) or not np.allclose(ts, slot.key_ts, atol=1e-9):
            raise DataError(f"key t's {ts}, the template's are {list(slot.key_ts)}",
                            path=source, gc=gc.name, field="keys",
                            fix="put one key at each of the template's t's")
        if gc.reparam is not None:
            raise DataError("a stretched GC (reparam) has no template layout", path=source,
                            gc=gc.name, field="reparam",
                            fix="condition on the GC before the stretch, or drop it")
        chosen[gc.name] = (k, gc.to_dict())
    order = sorted(chosen.values(), key=lambda x: x[0])
    target = torch.zeros(template.size, dtype=torch.float64)
    mask = torch.zeros(template.size, dtype=torch.bool)
    for k, d in order:
        sl = slice(int(template.offsets[k]), int(template.offsets[k + 1]))
        target[sl] = torch.from_numpy(gc_vector(d))
        mask[sl] = True
    return GCCondition(tuple(d["name"] for _, d in order), tuple(d for _, d in order), target,
                       mask, None if source is None else str(source))


def load_condition(path, template: GCTemplate) -> GCCondition:
    """A condition from a YAML file: an annotation (name, gcs: [...], mesh and normalize are
    ignored) as written by edit.py, sample.py, the editor or a dataset, or a bare list of GCs.
    A file sample.py re-centred and re-scaled (`decoder_frame: {center, scale}`) is mapped back
    to the decoder's frame first, so a generated shape's own GCs are a condition it can meet."""
    path = Path(path)
    if not path.is_file():
        raise DataError("condition file not found", path=path, field="gcs",
                        fix="pass gcs=<YAML with the GCs to keep>")
    try:
        d = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise DataError(f"not a readable YAML file ({str(e).splitlines()[0]})", path=path,
                        fix="correct the YAML syntax") from None
    gcs = d.get("gcs") if isinstance(d, dict) else d
    frame = d.get("decoder_frame") if isinstance(d, dict) else None
    if frame is not None:
        gcs = _to_decoder_frame(gcs, frame, path)
    return condition_from_gcs(template, gcs, source=path)


def _to_decoder_frame(gcs, frame, path: Path) -> list:
    """GC dicts under the inverse of x -> (x - center) * scale (`decoder_frame`)."""
    try:
        center = np.asarray(frame["center"], np.float64).reshape(3)
        scale = float(frame["scale"])
        if not (np.isfinite(center).all() and np.isfinite(scale) and scale > 0):
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise DataError(f"decoder_frame must be {{center: [x, y, z], scale: positive number}}, "
                        f"got {frame!r}", path=path, field="decoder_frame",
                        fix="remove decoder_frame if the GCs are in the model's frame") from None
    if not isinstance(gcs, list):
        return gcs  # condition_from_gcs names the problem
    out = []
    for g in gcs:  # a loop over GCs; a malformed one is left for condition_from_gcs to name
        try:
            out.append(similar_gc_dict(g, -center * scale, 1.0 / scale))
        except (KeyError, TypeError, ValueError, AttributeError):
            out.append(g)
    return out


# ---- residual and error ------------------------------------------------------------------------

def _active(shape_decoder, cond: GCCondition) -> torch.Tensor:
    """(M,) indices of the conditioned parameters that vary in the training data (the decoder
    holds the others at their constant value; `replace_gcs` sets them)."""
    return (cond.mask.to(shape_decoder.varying.device) & shape_decoder.varying).nonzero()[:, 0]


def residual(shape_decoder, latents: torch.Tensor, cond: GCCondition) -> torch.Tensor:
    """Latents (B, D) (original space) -> r = z(s) - z* over the active parameters: (B, M)
    float64, std units. Differentiable."""
    active = _active(shape_decoder, cond)
    z = shape_decoder.param_z(latents.to(shape_decoder.param_mean.dtype))
    z_star = shape_decoder.normalise(cond.target.to(z.device))
    return (z.double() - z_star.double()).index_select(1, active)


@torch.no_grad()
def gc_error(shape_decoder, latents: torch.Tensor, cond: GCCondition) -> torch.Tensor:
    """(B,) root-mean-square decoded GC error against the condition, in std units (0 if no
    conditioned parameter varies)."""
    r = residual(shape_decoder, latents, cond)
    if r.shape[1] == 0:
        return torch.zeros(len(latents), dtype=torch.float64)
    return r.pow(2).mean(1).sqrt()


def residual_jacobian(shape_decoder, diffusion, x: torch.Tensor, cond: GCCondition):
    """r (B, M) and J = dr/dx (B, M, D) at standardised latents x (B, D): one decoder pass over
    M copies of each latent and one backward pass of the sum of the M diagonal residuals."""
    B, D = x.shape
    with torch.enable_grad():
        r = residual(shape_decoder, diffusion.destandardise(x), cond).detach()
        M = r.shape[1]
        if M == 0:
            return r, x.new_zeros(B, 0, D)
        copies = x.detach().repeat_interleave(M, 0).requires_grad_(True)
        rows = residual(shape_decoder, diffusion.destandardise(copies), cond).reshape(B, M, M)
        J, = torch.autograd.grad(rows.diagonal(dim1=1, dim2=2).sum(), copies)
    return r, J.reshape(B, M, D)


def posterior_step(shape_decoder, diffusion, x: torch.Tensor, cond: GCCondition,
                   strength: float, scale) -> torch.Tensor:
    """The change of latents x (B, D) (standardised, float64) that conditions them on the GCs:
    (J^T J + (1 / (strength scale))^2 I)^-1 J^T r, r and J = dr/dx the decoded GC residual and
    its Jacobian at x. This is the posterior mean shift of x ~ N(x, scale^2 I) observed through
    the linearised decoder with noise std 1/strength (std units): directions the condition does
    not constrain (J small) do not move. scale: float or (B,)."""
    if float(strength) == 0.0:                # no condition: an infinitely wide prior step
        return torch.zeros_like(x)
    r, J = residual_jacobian(shape_decoder, diffusion, x, cond)
    if r.shape[1] == 0:                       # nothing conditioned varies: nothing to guide
        return torch.zeros_like(x)
    prior = (1.0 / (float(strength) * torch.as_tensor(scale, dtype=x.dtype))) ** 2
    eye = torch.eye(x.shape[1], dtype=x.dtype, device=x.device)
    A = J.transpose(1, 2) @ J + prior.reshape(-1, 1, 1) * eye
    # A is symmetric positive definite: Cholesky. (torch.linalg.solve's batched LU failed here
    # with 2 threads: "Intel oneMKL ERROR: Parameter 6 was incorrect on entry to DLASWP")
    return torch.cholesky_solve(J.transpose(1, 2) @ r[..., None], torch.linalg.cholesky(A))[..., 0]


class GuidedDenoiser:
    """D~(x; sigma) = D(x; sigma) - posterior_step at D with scale c_out(sigma) (the std of the
    clean latent given x at noise level sigma, for unit-variance data), for `edm_sampler`
    (float64 x, 0-d sigma)."""

    def __init__(self, net, diffusion, shape_decoder, cond: GCCondition, strength: float):
        self.net, self.diffusion, self.shape_decoder = net, diffusion, shape_decoder
        self.cond, self.strength = cond, float(strength)
        self.sigma_min = getattr(net, "sigma_min", 0.0)   # what edm_sampler clips to
        self.sigma_max = getattr(net, "sigma_max", float("inf"))

    def __call__(self, x: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
        D = self.net(x, sigma).to(torch.float64)
        if self.strength == 0.0:
            return D
        c_out = self.net.coefficients(torch.as_tensor(sigma, dtype=torch.float64))[1]
        return D - posterior_step(self.shape_decoder, self.diffusion, D, self.cond,
                                  self.strength, c_out)


def project(shape_decoder, diffusion, latents: torch.Tensor, cond: GCCondition, strength: float,
            steps: int) -> torch.Tensor:
    """`steps` posterior steps (scale 1: the prior std of standardised latents) on latents
    (B, D) (original space) after sampling, each halved (at most 6 times) until it lowers the
    GC error (else not taken): a far target makes the linearised step overshoot. float32."""
    x = diffusion.standardise(latents.to(torch.float64))

    def err(x):
        return gc_error(shape_decoder, diffusion.destandardise(x), cond)

    for _ in range(int(steps)):
        step, before = posterior_step(shape_decoder, diffusion, x, cond, strength, 1.0), err(x)
        for _ in range(6):
            worse = err(x - step) >= before
            if not bool(worse.any()):
                break
            step = torch.where(worse[:, None], 0.5 * step, step)
        x = torch.where((err(x - step) < before)[:, None], x - step, x)
    return diffusion.destandardise(x).to(torch.float32)


def conditional_latents(gen, cond: GCCondition, indices, seed: int, strength: float,
                        project_steps: int, sampler: dict | None = None) -> torch.Tensor:
    """Latents (len(indices), D) of conditioned shapes `indices` under `seed`: the EDM samples
    of `gen.sample_latents` (same noise) guided toward `cond`, then `project_steps` projection
    steps. strength 0: exactly `gen.sample_latents(indices, seed)`."""
    if not (np.isfinite(float(strength)) and float(strength) >= 0.0):
        raise DataError(f"guidance strength must be a number >= 0, got {strength}",
                        field="condition.strength",
                        fix="use 0 (unconditional) or e.g. 30 (match the GCs to ~0.07 std)")
    if int(project_steps) < 0:
        raise DataError(f"project_steps must be >= 0, got {project_steps}",
                        field="condition.project_steps", fix="use e.g. 0 .. 10")
    sd = gen.shape_latent.shape_decoder
    guide = None
    if float(strength) > 0:
        def guide(diffusion, net):
            return GuidedDenoiser(net, diffusion, sd, cond, strength)
    latents = gen.sample_latents(indices, seed, guide=guide, **(sampler or {}))
    if float(strength) > 0 and int(project_steps) > 0:
        latents = project(sd, gen.diffusion, latents, cond, strength, project_steps)
    return latents


# ---- output ------------------------------------------------------------------------------------

def replace_gcs(gcs: list[dict], cond: GCCondition) -> list[dict]:
    """Decoded GC dicts (template order) with the conditioned ones replaced by the condition's
    (verbatim values, canonical annotation format)."""
    given = dict(zip(cond.names, cond.gcs))
    return [dict(given[d["name"]]) if d["name"] in given else d for d in gcs]


def with_given_gcs(shape, cond: GCCondition):
    """A decoded `ngc_gen.shape.Shape` whose conditioned GCs are the condition's, verbatim (its
    codes and other GCs kept): "replace"."""
    from ngc_gen.geometry import GeneralizedCylinder

    return shape.replaced(gcs=[GeneralizedCylinder.from_dict(d)
                               for d in replace_gcs(shape.gc_dicts(), cond)])
