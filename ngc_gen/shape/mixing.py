"""Part mixing, the one implementation behind `Shape.with_part`, the edit op `mix` and
`sample.py mode=mix`: which GC and which features a mixed part gets."""
from __future__ import annotations

import numpy as np
import torch

from ngc_gen.geometry import GeneralizedCylinder

from .features import PartFeatures

GEOMETRIES = ("source", "target")


def start_frame(gc: GeneralizedCylinder) -> np.ndarray:
    """(4, 3) rows: curve point, tangent, normal, binormal at the GC's start."""
    s = torch.zeros(1, dtype=torch.float64)
    return torch.cat(gc.frame(s, s)).numpy()


def mixed_parts(targets: list[GeneralizedCylinder], sources: list[GeneralizedCylinder],
                codes, weight=None, geometry: str = "source", labels: list[str] | None = None
                ) -> list[tuple[GeneralizedCylinder, PartFeatures]]:
    """(GC, features) for each target GC that takes the matching source part.

    geometry="source" (default): the source parts' GCs, moved by the one rigid motion that puts
    the first source GC's start frame on the first target's start frame (the joint; a head and
    its ears move together), each named as its target, so the part looks like the source's;
    "target": the targets' own GCs, only the features blended inside them. weight: w(t), or
    None for replace (exactly the source's features)."""
    if geometry not in GEOMETRIES:
        raise ValueError(f"geometry must be one of {GEOMETRIES}, got {geometry!r}")
    if len(targets) != len(sources) or len(codes) != len(sources) or not targets:
        raise ValueError("give one source GC and code per target GC")
    labels = labels or [s.name for s in sources]
    gcs = list(targets)
    if geometry == "source":
        a, b = start_frame(targets[0]), start_frame(sources[0])
        R = a[1:].T @ b[1:]
        t = a[0] - R @ b[0]
        gcs = [s.transformed(R, t).replace(name=g.name) for s, g in zip(sources, targets)]
    return [(g, PartFeatures(torch.as_tensor(c).detach().clone(), weight, lab))
            for g, c, lab in zip(gcs, codes, labels)]
