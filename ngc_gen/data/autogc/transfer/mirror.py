"""A missing part of a symmetric pair stands in as its found partner's mirror image.

A part the skeleton has no branch for (a crocodile's splayed hind foot, flat under the body,
pruned with the spurs) otherwise stands in as a stub toward where the template puts its end,
or as a small GC at its attachment: on an animal whose proportions are not the template's
(the crocodile's hind legs sit mid-body, the template's at the rump) that lands on the wrong
surface, or none. The template says the pair are mirror images: the found partner's GC
mirrored across the body's mid-plane lies on the missing part when the mesh is symmetric;
it stands in when it holds at least HELD x as much surface as its partner does (else the
pose or the mesh is not symmetric there, and the stub stands in).
"""
from __future__ import annotations

import numpy as np

from ngc_gen.geometry import GeneralizedCylinder

from .tree import BodyFrame

HELD = 0.5  # the mirror image stands in when it holds this x the surface its partner holds


def mirrored_gc(gc: GeneralizedCylinder, body: BodyFrame, name: str) -> GeneralizedCylinder:
    """`gc` mirrored across the body's mid-plane (body left = 0), named `name`."""
    d = gc.to_dict()
    flip = body.R.T @ np.diag([1.0, -1.0, 1.0]) @ body.R       # a direction's mirror image
    pts = body.to_body(np.asarray(d["curve"]["points"], dtype=np.float64))
    pts[:, 1] *= -1.0
    d["curve"] = {**d["curve"], "points": body.to_world(pts).tolist()}
    d["up"] = (flip @ np.asarray(d["up"], dtype=np.float64)).tolist()
    d["name"] = name
    return GeneralizedCylinder.from_dict(d)


def mirror_stand_in(partner: GeneralizedCylinder, body: BodyFrame, name: str,
                    surface: np.ndarray) -> GeneralizedCylinder | None:
    """The partner's mirror image (``mirrored_gc``) when it holds at least HELD x the surface
    samples (S, 3) the partner holds, else None."""
    m = mirrored_gc(partner, body, name)
    held = int(np.count_nonzero(np.asarray(m.contains(surface), bool)))
    own = int(np.count_nonzero(np.asarray(partner.contains(surface), bool)))
    return m if own and held >= HELD * own else None
