"""`Shape`: GCs + per-GC codes + decoder, and the one NGC sdf function.

The field of a shape at a world point q is, over the GCs j that contain q, the blend of
decoder(code_j, rel_j(q)) weighted by where q lies in each GC (`blend`: the width of the fade,
`ngc_gen.geometry.union`), or their minimum (blend 0; the smooth minimum of width `smooth`); a
point no GC contains is outside (positive background). Shapes are values: edits return new
shapes (`replaced`, `with_part`, `edited`), so a before/after pair shares the decoder and
differs only where it was edited.
"""
from __future__ import annotations

import hashlib
from typing import Callable, Iterable

import numpy as np
import torch

from ngc_gen.extract import FieldCache, extract_mesh
from ngc_gen.geometry import GeneralizedCylinder, smooth_min
from ngc_gen.geometry.union import BlendAccumulator

from .features import PartFeatures, blend_features

#: background SDF value for `Shape.sdf` at points outside every GC (world units)
OUTSIDE = 1.0


class Shape:
    """gcs: K GeneralizedCylinders; codes: (K, code_dim); decoder: an NGCDecoder (features,
    sdf_from_features); mixes: {gc index: PartFeatures}; smooth: smooth-union width (0: min);
    blend, blend_k: blended-union width (0: the min / smooth min) and softness (the fit's
    recorded union, `ngc_gen.geometry.union`)."""

    def __init__(self, gcs: Iterable[GeneralizedCylinder], codes: torch.Tensor, decoder, *,
                 name: str = "shape", mixes: dict[int, PartFeatures] | None = None,
                 smooth: float = 0.0, blend: float = 0.0, blend_k: float = 0.0,
                 info: dict | None = None,
                 cache: FieldCache | None = None):
        self.gcs = list(gcs)
        self.codes = torch.as_tensor(codes).detach().float()
        self.decoder = decoder
        self.name = str(name)
        self.mixes = dict(mixes or {})
        self.smooth = float(smooth)
        self.blend, self.blend_k = float(blend), float(blend_k)
        self.info = dict(info or {})
        # per-GC field values of this shape and every shape edited from it (`replaced` passes
        # it on): after an edit only GCs with a new `key` are evaluated again
        self.cache = cache if cache is not None else FieldCache()
        if self.codes.ndim != 2 or len(self.codes) != len(self.gcs):
            raise ValueError(f"a shape needs one code per GC: {len(self.gcs)} GCs, codes of "
                             f"shape {tuple(self.codes.shape)}")
        if not self.smooth >= 0.0:
            raise ValueError(f"smooth-union width must be >= 0, got {smooth}")
        if self.blend and self.smooth:
            raise ValueError(f"a shape has one union: a smooth min (smooth={smooth}) or a blend "
                             f"(blend={blend}), not both")
        for j, m in self.mixes.items():
            if not 0 <= j < len(self.gcs):
                raise ValueError(f"a part mix targets GC index {j}; the shape has "
                                 f"{len(self.gcs)} GCs")
            if m.code.shape != self.codes[j].shape:
                raise ValueError(f"a mixed part's code has shape {tuple(m.code.shape)}, this "
                                 f"network's codes {tuple(self.codes[j].shape)}: mix parts of "
                                 "shapes fitted with the same network")

    # ---- names --------------------------------------------------------------------------------
    @property
    def gc_names(self) -> list[str]:
        return [g.name for g in self.gcs]

    def index(self, gc: str | int) -> int:
        """Index of a GC by name (or an index, checked)."""
        names = self.gc_names
        if isinstance(gc, (int, np.integer)) and not isinstance(gc, bool):
            if not 0 <= int(gc) < len(names):
                raise KeyError(f"GC index {gc} out of range; shape '{self.name}' has "
                               f"{len(names)} GCs")
            return int(gc)
        if gc not in names:
            raise KeyError(f"shape '{self.name}' has no GC named {gc!r}; its GCs are {names}")
        return names.index(gc)

    def gc_dicts(self) -> list[dict]:
        return [g.to_dict() for g in self.gcs]

    # ---- the one sdf function -------------------------------------------------------------------
    def gc_sdf(self, j: int, rel: torch.Tensor) -> torch.Tensor:
        """SDF of GC j at relative coordinates rel (M, 3) [u, a, b] -> (M,), with its part mix."""
        dec, code = self.decoder, self.codes[j].to(rel.device)
        mix = self.mixes.get(j)
        with torch.no_grad():
            if mix is None:
                return dec(code.expand(len(rel), -1), rel)
            u = rel[:, 0]
            fb = dec.features(mix.code.to(rel.device).expand(len(rel), -1), u)
            if mix.weight is None:
                feats = fb
            else:
                fa = dec.features(code.expand(len(rel), -1), u)
                feats = blend_features(fa, fb, ((u + 1.0) * 0.5).clamp(0.0, 1.0), mix.weight)
            return dec.sdf_from_features(rel, feats)

    def rows(self, gc_index: torch.Tensor, rel: torch.Tensor) -> torch.Tensor:
        """rows_fn for `ngc_gen.extract.extract_mesh`: SDF at rows of relative coordinates rel
        (M, 3) of GCs gc_index (M,), one batched decoder call for the unmixed GCs
        (`NGCDecoder.sdf_rows`: end features once per GC), `gc_sdf` for each mixed GC."""
        with torch.inference_mode():
            codes = self.codes.to(rel.device)
            if not self.mixes:
                return self.decoder.sdf_rows(codes, gc_index, rel)
            out = torch.empty(len(rel), dtype=rel.dtype, device=rel.device)
            mixed = torch.zeros(len(rel), dtype=torch.bool, device=rel.device)
            for j in self.mixes:  # a loop over the mixed GCs (a few), never over points
                m = gc_index == j
                if bool(m.any()):
                    out[m] = self.gc_sdf(j, rel[m]).to(out.dtype)
                mixed |= m
            plain = ~mixed
            if bool(plain.any()):
                out[plain] = self.decoder.sdf_rows(codes, gc_index[plain], rel[plain])
            return out

    def sdf(self, points) -> torch.Tensor:
        """World points (N, 3) -> (N,) float32: the blend (or min, smooth min) over the GCs
        containing each point; `OUTSIDE` where none does. The rows of all GCs go through one
        decoder call (`rows`, the mesher's values)."""
        q = torch.as_tensor(np.asarray(points) if not isinstance(points, torch.Tensor) else points,
                            dtype=torch.float64)
        out = torch.full((len(q),), float("inf"), dtype=torch.float32)
        held = []  # (GC, point indices, relative coordinates, measure) per GC holding points
        for j, gc in enumerate(self.gcs):  # a loop over the K GCs, never over points
            rel, measure = gc.relative_inside(q)  # one closest-point solve per point and GC
            idx = np.flatnonzero(measure <= 1.0)
            if len(idx):
                held.append((j, idx, rel[idx].float(), measure[idx]))
        if not held:
            return out.fill_(OUTSIDE)
        values = self.rows(torch.from_numpy(np.concatenate([np.full(len(h[1]), h[0])
                                                            for h in held])),
                           torch.cat([h[2] for h in held])).float()
        mixed = BlendAccumulator(len(q), self.blend, self.blend_k) if self.blend else None
        start = 0
        for _, idx, _, measure in held:  # GCs
            v = values[start:start + len(idx)]
            start += len(idx)
            if mixed is not None:
                mixed.add(idx, v.numpy(), measure)
                continue
            t = torch.from_numpy(idx)
            cur = out[t]
            out[t] = torch.where(torch.isinf(cur), v, smooth_min(cur, v, self.smooth))
        if mixed is not None:
            out = torch.from_numpy(mixed.result())
        return out.masked_fill_(torch.isinf(out), OUTSIDE)

    # ---- meshes ---------------------------------------------------------------------------------
    def key(self, j: int) -> str:
        """Identity of GC j's field (its parameters, code, mix and the decoder object): equal
        keys give equal values, so a per-GC value cache can skip GCs an edit did not change."""
        h = hashlib.sha1(f"{id(self.decoder)}:{sorted(self.gcs[j].to_dict().items())!r}".encode())
        h.update(self.codes[j].numpy().tobytes())
        if j in self.mixes:
            for part in self.mixes[j].key():
                h.update(part if isinstance(part, bytes) else part.encode())
        return h.hexdigest()

    def mesh(self, resolution: int = 256, bound: float = 1.0, method: str = "sparse",
             incremental: bool = True, **kwargs):
        """ExtractionResult (mesh, stats) of the shape's zero level set on a resolution^3 grid
        over [-bound, bound]^3 (`ngc_gen.extract.extract_mesh`, the shape's union: blend of
        width `blend`, or min / smooth min of width `smooth` over the GCs). method "sparse"
        (default) keeps per-GC values in `self.cache` unless incremental=False; "prefiltered" /
        "dense" are the exact references; kwargs go
        to extract_mesh (chunk, fixed_batch, keep_values, progress, ...)."""
        if method == "sparse" and incremental:
            kwargs.update(cache=self.cache, gc_keys=[self.key(j) for j in range(len(self.gcs))])
        return extract_mesh(self.gcs, self.rows, int(resolution), float(bound), method=method,
                            smooth=self.smooth, blend=self.blend, blend_k=self.blend_k,
                            **kwargs)

    # ---- edits (new shapes) ---------------------------------------------------------------------
    def replaced(self, **changes) -> "Shape":
        """A copy with some of gcs, codes, decoder, name, mixes, smooth, blend, info replaced."""
        kw = dict(gcs=self.gcs, codes=self.codes, decoder=self.decoder, name=self.name,
                  mixes=self.mixes, smooth=self.smooth, blend=self.blend,
                  blend_k=self.blend_k, info=self.info, cache=self.cache)
        kw.update(changes)
        return Shape(kw.pop("gcs"), kw.pop("codes"), kw.pop("decoder"), **kw)

    def with_part(self, gc, source: "Shape", source_gc=None, weight: Callable | None = None,
                  geometry: str = "source") -> "Shape":
        """Part mixing (`ngc_gen.shape.mixing.mixed_parts`): GC `gc` (a name, index, or a list
        of them moving together, e.g. a head and its ears) takes `source`'s GC(s) `source_gc`
        (default: the same names). geometry="source" (default) takes the source part's GCs,
        attached at this shape's joint, and its features; "target" keeps this shape's GCs and
        blends the features inside them by w(t) = weight(t) (None: replace)."""
        from .mixing import mixed_parts

        targets = [self.index(g) for g in (gc if isinstance(gc, (list, tuple)) else [gc])]
        if source_gc is None:
            src = [source.index(self.gc_names[j]) for j in targets]
        else:
            src = [source.index(g) for g in
                   (source_gc if isinstance(source_gc, (list, tuple)) else [source_gc])]
        parts = mixed_parts([self.gcs[j] for j in targets], [source.gcs[k] for k in src],
                            [source.codes[k] for k in src], weight, geometry,
                            [f"{source.name}/{source.gcs[k].name}" for k in src])
        gcs, mixes = list(self.gcs), dict(self.mixes)
        for j, (g, feats) in zip(targets, parts):
            gcs[j], mixes[j] = g, feats
        return self.replaced(gcs=gcs, mixes=mixes)

    def edited(self, program, sources=None) -> "Shape":
        """The shape after an edit program (`ngc_gen.edit.EditProgram`): the program applies
        itself (`program.apply_to(shape, sources)`), so this layer needs no edit import."""
        return program.apply_to(self, sources)

    def __repr__(self) -> str:
        mixed = f", mixed {sorted(self.gc_names[j] for j in self.mixes)}" if self.mixes else ""
        return f"Shape({self.name!r}, {len(self.gcs)} GCs {self.gc_names}{mixed})"
