"""Shape decoder for generation (docs/generation.md): one latent per shape -> the GC parameters
of a shared template and one NGC code per GC.

The template (`GCTemplate`) fixes what every shape shares: the GC names and order, each curve's
Bezier degree, each GC's `up` vector and the key t's. What varies is a flat parameter vector
theta (`GCTemplate.vector` / `GCTemplate.gc_dicts`), per GC in template order:

    control points (degree+1, 3) | log key radii (keys, 2) | key twists (keys,) deg | log caps (2,)

Radii and caps are stored as logs, so any decoded value maps to a positive one. Parameters are
handled in per-parameter std units around the training set's mean, z = (theta - mean) / std,
held within +-b std (b = `bound`, default 5) so decoded GCs stay non-degenerate for any
latent; a parameter that never varies in the data (std 0: a symmetry plane, an untwisted part)
is decoded exactly at its constant value. With `explicit` latents (the default) z is part of
the latent itself; otherwise an MLP head predicts it (`ShapeDecoder`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from ngc_gen.data.errors import DataError

from .mlp import mlp

#: A parameter whose std over the training shapes is at most this is held at its mean.
CONSTANT_STD = 1e-5
FIELDS = ("points", "log_radii", "twist", "log_caps")


@dataclass(frozen=True)
class GCSlot:
    """One GC of the template: name, Bezier degree, frame `up`, key t's."""

    name: str
    degree: int
    up: tuple[float, float, float]
    key_ts: tuple[float, ...]

    @property
    def size(self) -> int:
        return 3 * (self.degree + 1) + 3 * len(self.key_ts) + 2

    def to_dict(self) -> dict:
        return {"name": self.name, "degree": int(self.degree),
                "up": [float(x) for x in self.up], "key_ts": [float(t) for t in self.key_ts]}


class GCTemplate:
    """The shared GC layout of a dataset and the GC dicts <-> parameter vector map."""

    def __init__(self, slots):
        self.slots = tuple(s if isinstance(s, GCSlot) else
                           GCSlot(s["name"], int(s["degree"]), tuple(float(x) for x in s["up"]),
                                  tuple(float(t) for t in s["key_ts"])) for s in slots)
        if not self.slots:
            raise DataError("a GC template needs at least one GC")
        names = [s.name for s in self.slots]
        if len(set(names)) != len(names):
            raise DataError(f"GC names in a template must be unique, got {names}")
        self.offsets = np.cumsum([0] + [s.size for s in self.slots])

    # ---- construction / serialisation ------------------------------------------------------
    @classmethod
    def from_gcs(cls, gcs: list[dict], where: str | None = None) -> "GCTemplate":
        """The template of one shape's GC dicts (annotation order); `where` names them in errors."""
        if not isinstance(gcs, list) or not gcs:
            raise DataError("a shape needs a non-empty list of GCs to define a template",
                            path=where)
        slots = []
        for d in gcs:
            _check_gc(d, where)
            slots.append(GCSlot(str(d["name"]), len(d["curve"]["points"]) - 1,
                                tuple(float(x) for x in d.get("up") or (0.0, 0.0, 1.0)),
                                tuple(float(k.get("t", 0.0)) for k in d["keys"])))
        return cls(slots)

    @classmethod
    def from_dict(cls, d: dict) -> "GCTemplate":
        return cls(d["gcs"])

    def to_dict(self) -> dict:
        """Plain dict (checkpoint hyper-parameters)."""
        return {"gcs": [s.to_dict() for s in self.slots]}

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.slots]

    @property
    def n_gcs(self) -> int:
        return len(self.slots)

    @property
    def size(self) -> int:
        """Length P of the parameter vector."""
        return int(self.offsets[-1])

    def index(self, name: str) -> int:
        """Position of GC `name` in the template (DataError listing the names if absent)."""
        if name not in self.names:
            raise DataError(f"no GC named {name!r} in the template", field="part",
                            fix=f"use one of {self.names}")
        return self.names.index(name)

    def fields(self) -> list[tuple[str, str, slice]]:
        """(gc name, field, slice into the vector) for every field of every GC, in order."""
        out = []
        for s, o in zip(self.slots, self.offsets):
            sizes = (3 * (s.degree + 1), 2 * len(s.key_ts), len(s.key_ts), 2)
            for f, n in zip(FIELDS, sizes):
                out.append((s.name, f, slice(int(o), int(o) + n)))
                o += n
        return out

    # ---- GC dicts <-> parameter vector -----------------------------------------------------
    def check(self, gcs: list[dict], where: str | None = None) -> None:
        """DataError unless `gcs` (GC dicts) follow this template: names in order, Bezier curves
        of the template's degrees, the same up vectors and key t's, no reparam."""
        if not isinstance(gcs, list) or len(gcs) != self.n_gcs:
            n = len(gcs) if isinstance(gcs, list) else "no"
            raise DataError(f"has {n} GCs, the template has {self.n_gcs} ({self.names})",
                            path=where, fix="give every shape the same GCs in the same order")
        for i, (d, s) in enumerate(zip(gcs, self.slots)):
            _check_gc(d, where)
            name = d.get("name")
            if name != s.name:
                raise DataError(f"GC {i} is named {name!r}, the template has {s.name!r} there",
                                path=where, gc=str(name), field="name",
                                fix=f"order the GCs as {self.names}")
            deg = len(d["curve"]["points"]) - 1
            if deg != s.degree:
                raise DataError(f"Bezier degree {deg}, the template's is {s.degree}", path=where,
                                gc=s.name, field="curve.points",
                                fix=f"give {s.degree + 1} control points")
            up = tuple(float(x) for x in d.get("up") or (0.0, 0.0, 1.0))
            # 1e-4: the rounding of a YAML file and of a frame turned into the template's
            # (0.006 degrees); a real difference between shapes is far larger
            if not np.allclose(up, s.up, atol=1e-4):
                raise DataError(f"up {list(up)}, the template's is {list(s.up)}", path=where,
                                gc=s.name, field="up", fix="use the same up vector in every shape")
            ts = tuple(float(k.get("t", 0.0)) for k in d["keys"])
            if len(ts) != len(s.key_ts) or not np.allclose(ts, s.key_ts, atol=1e-9):
                raise DataError(f"key t's {list(ts)}, the template's are {list(s.key_ts)}",
                                path=where, gc=s.name, field="keys",
                                fix="put the keys at the same t's in every shape")

    def vector(self, gcs: list[dict], where: str | None = None) -> np.ndarray:
        """GC dicts (template order) -> theta (P,) float64."""
        self.check(gcs, where)
        return np.concatenate([gc_vector(d) for d in gcs])

    def gc_dicts(self, theta) -> list[dict]:
        """theta (P,) (numpy or torch) -> GC dicts in annotation format (twist in degrees)."""
        v = (theta.detach().cpu().double().numpy() if torch.is_tensor(theta)
             else np.asarray(theta, np.float64))
        if v.shape != (self.size,):
            raise ValueError(f"theta must have shape ({self.size},), got {v.shape}")
        out = []
        for s, o in zip(self.slots, self.offsets):
            n_pts, n_keys = 3 * (s.degree + 1), len(s.key_ts)
            pts = v[o:o + n_pts].reshape(-1, 3)
            o += n_pts
            radii = np.exp(v[o:o + 2 * n_keys]).reshape(-1, 2)
            o += 2 * n_keys
            twist = v[o:o + n_keys]
            o += n_keys
            caps = np.exp(v[o:o + 2])
            out.append({"name": s.name,
                        "curve": {"type": "bezier", "points": pts.tolist()},
                        "up": list(s.up),
                        "keys": [{"t": t, "radii": r.tolist(), "twist": float(w)}
                                 for t, r, w in zip(s.key_ts, radii, twist)],
                        "caps": caps.tolist()})
        return out


def gc_vector(d: dict) -> np.ndarray:
    """One GC dict -> its slice of theta (float64): points | log radii | twists | log caps."""
    keys = d["keys"]
    radii = [[float(k["radii"])] * 2 if np.isscalar(k["radii"]) else k["radii"] for k in keys]
    return np.concatenate([np.asarray(d["curve"]["points"], np.float64).ravel(),
                           np.log(np.asarray(radii, np.float64)).ravel(),
                           np.asarray([float(k.get("twist", 0.0)) for k in keys], np.float64),
                           np.log(np.asarray(d.get("caps", (0.1, 0.1)), np.float64))])


def _check_gc(d, where) -> None:
    """The structure a template GC needs (the geometry layer validates values later)."""
    if not isinstance(d, dict) or "name" not in d:
        raise DataError(f"each GC must be a mapping with a name, got {d!r}"[:200], path=where)
    name = str(d["name"])
    curve = d.get("curve")
    if not isinstance(curve, dict) or curve.get("type") != "bezier" \
            or not isinstance(curve.get("points"), list) or len(curve["points"]) < 2:
        raise DataError("the generative template needs Bezier curves (type: bezier, >= 2 "
                        "control points)", path=where, gc=name, field="curve",
                        fix="annotate every shape with Bezier GCs of the same degree")
    if d.get("reparam") is not None:
        raise DataError("a reparameterised GC (after a stretch edit) has no fixed layout",
                        path=where, gc=name, field="reparam",
                        fix="train on unedited annotations")
    if not isinstance(d.get("keys"), list) or not d["keys"]:
        raise DataError("needs a list of keys", path=where, gc=name, field="keys")


class ShapeDecoder(nn.Module):
    """s (B, in_dim) -> (normalised GC parameters (B, P), NGC codes (B, K, code_dim)).

    explicit (the default in conf/shape_latent): the first P entries of a latent ARE the GC
    parameters in std units, s = [z (P), free (latent_dim)], and the MLP maps the whole of s to
    the codes. A latent then holds any GC parameters exactly (the decoded GCs of a conditional
    sample are what guidance or inpainting put there), and the codes are learned as a function
    of the GCs. Otherwise (checkpoints from before): s (latent_dim) -> MLP -> both heads, the
    parameters as a bounded residual b tanh(out / b), whose range is what 48 training shapes
    span (held-out creatures' GCs lie 0.26 std rms outside their affine hull: bench/condition.py).

    The parameter statistics (`param_mean`, `param_std`: buffers, so they travel in the
    checkpoint) must be set from the training shapes with `set_param_stats` before use.
    """

    def __init__(self, latent_dim: int, n_params: int, n_gcs: int, code_dim: int,
                 hidden: int = 256, layers: int = 2, bound: float = 5.0, explicit: bool = True):
        super().__init__()
        self.latent_dim, self.n_params, self.n_gcs, self.code_dim = (latent_dim, n_params,
                                                                     n_gcs, code_dim)
        self.bound, self.explicit = float(bound), bool(explicit)
        self.in_dim = latent_dim + (n_params if self.explicit else 0)
        self.trunk = mlp(self.in_dim, hidden, layers)
        self.param_head = None if self.explicit else nn.Linear(hidden, n_params)
        self.code_head = nn.Linear(hidden, n_gcs * code_dim)
        if self.param_head is not None:
            nn.init.zeros_(self.param_head.weight)  # starts at the mean shape
            nn.init.zeros_(self.param_head.bias)
        self.register_buffer("param_mean", torch.zeros(n_params))
        self.register_buffer("param_std", torch.zeros(n_params))

    @torch.no_grad()
    def set_param_stats(self, vectors) -> None:
        """Mean and std (population) of training parameter vectors (N, P); std <= CONSTANT_STD
        is set to 0, which holds that parameter at its mean."""
        v = torch.as_tensor(np.asarray(vectors), dtype=torch.float64)
        if v.ndim != 2 or v.shape[1] != self.n_params or len(v) < 1:
            raise ValueError(f"need parameter vectors (N >= 1, {self.n_params}), got "
                             f"{tuple(v.shape)}")
        std = v.std(0, unbiased=False) if len(v) > 1 else torch.zeros(v.shape[1])
        self.param_mean.copy_(v.mean(0))
        self.param_std.copy_(torch.where(std > CONSTANT_STD, std, torch.zeros_like(std)))

    @property
    def varying(self) -> torch.Tensor:
        """(P,) bool: parameters that vary over the training shapes (the ones that are learned)."""
        return self.param_std > 0

    def normalise(self, theta: torch.Tensor) -> torch.Tensor:
        """Raw parameters (..., P) -> std units around the mean (constant ones -> 0)."""
        std = torch.where(self.varying, self.param_std, torch.ones_like(self.param_std))
        return torch.where(self.varying, (theta - self.param_mean) / std,
                           torch.zeros_like(theta))

    def params(self, z: torch.Tensor) -> torch.Tensor:
        """Normalised parameters (..., P) -> raw theta (..., P)."""
        return self.param_mean + self.param_std * z

    def forward(self, s: torch.Tensor):
        """s (B, in_dim) -> z (B, P) in std units, within +-bound; codes (B, K, C)."""
        h = self.trunk(s)
        codes = self.code_head(h).reshape(len(s), self.n_gcs, self.code_dim)
        return self._z(s, h), codes

    def param_z(self, s: torch.Tensor) -> torch.Tensor:
        """s (B, in_dim) -> z (B, P) only (no codes: conditional sampling's Jacobians)."""
        return self._z(s, None if self.explicit else self.trunk(s))

    def gc_part(self, z: torch.Tensor) -> torch.Tensor:
        """Explicit latents: the GC entries of a latent for parameters z (B, P) in std units
        (constant parameters 0); concatenated with the free entries it is a latent."""
        return torch.where(self.varying, z, torch.zeros_like(z))

    def _z(self, s: torch.Tensor, h: torch.Tensor | None) -> torch.Tensor:
        b = self.bound
        if self.explicit:  # the latent's own entries, clamped: any value decodes to a GC
            return self.gc_part(s[:, :self.n_params].clamp(-b, b))
        return b * torch.tanh(self.param_head(h) / b)

    def decode(self, s: torch.Tensor):
        """s (B, in_dim) -> (raw theta (B, P), codes (B, K, C))."""
        z, codes = self(s)
        return self.params(z), codes


def param_errors(template: GCTemplate, theta_pred, theta_true) -> dict:
    """Readable errors of decoded parameters against annotated ones (both (N, P) raw):
    control points: mean / max distance; radii and caps: mean |relative| error; twist: mean
    |difference| in degrees."""
    p = np.asarray(theta_pred, np.float64)
    t = np.asarray(theta_true, np.float64)
    d = {f: [] for f in FIELDS}
    for _, f, sl in template.fields():
        d[f].append((p[:, sl], t[:, sl]))
    pts = np.concatenate([np.linalg.norm((a - b).reshape(len(a), -1, 3), axis=-1)
                          for a, b in d["points"]], 1)
    rel = lambda f: float(np.mean(np.concatenate(  # noqa: E731
        [np.abs(np.exp(a - b) - 1.0) for a, b in d[f]], 1)))
    tw = np.concatenate([np.abs(a - b) for a, b in d["twist"]], 1)
    return {"point_mean": float(pts.mean()), "point_max": float(pts.max()),
            "radius_rel": rel("log_radii"), "cap_rel": rel("log_caps"),
            "twist_deg": float(tw.mean())}

