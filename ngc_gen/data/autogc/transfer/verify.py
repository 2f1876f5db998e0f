"""Right names or a refusal: a match checked against what the template says about itself.

After the correspondence, in the body frame of the orientation tried (front, left, up of the
surface's bounding box over its half extents), each check compares where the matched parts lie
with where the template's `place` puts them:
- ends: the parts off the torso's middle (neck, head, tail) lie on the template's side of the
  torso, front or back (head and tail at opposite ends, the neck toward the head);
- ground: the parts that reach down (legs) end below the torso's middle, all of them;
- sides: of a symmetric pair, the part the template puts on the left lies left of its partner;
- mirror: a symmetric pair's paths are alike in length (within MIRROR_RATIO);
- thickness: of two end parts at opposite ends, the one the template makes THICK_RATIO x
  thicker (a neck against a tail) is not clearly the thinner here: a frame turned back to front is
  consistent in itself, and only this tells it (the head's chain on the tail).
The first failing check names the mesh's refusal when no orientation passes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.data.autogc.template import Template

END_FRONT = 0.3    # a part whose place's middle lies this far (body units) front or back is an end
LEG_DOWN = 0.5     # a part whose place ends this much lower than it starts reaches the ground
SIDE = 0.2         # a symmetric part this far left or right tells left from right
MIRROR_RATIO = 2.5  # a symmetric pair's path lengths differ by at most this factor
THICK_RATIO = 1.5  # end parts this much thicker in the template must not be clearly thinner
THINNER = 0.85     # on the mesh (their outer halves' inscribed radii at most this ratio): a short
                   # tail's path runs inside the rump, as thick as an alpaca's neck


@dataclass(frozen=True)
class Verdict:
    """failed: the first check that failed, with what it saw (None: all passed)."""

    failed: str | None

    @property
    def ok(self) -> bool:
        return self.failed is None


def _mid(place: dict) -> np.ndarray:
    return (np.asarray(place["start"], float) + np.asarray(place["end"], float)) / 2.0


def verify(template: Template, paths: dict[str, np.ndarray], nodes_body: np.ndarray,
           radius: np.ndarray) -> Verdict:
    """The checks of the module docstring on matched `paths` (template GC name -> node indices,
    root side first) with the tree's nodes in body coordinates `nodes_body` (N, 3) and their
    inscribed radii `radius` (N,)."""
    root = next(g.name for g in template.gcs if g.parent is None)
    if root not in paths:
        return Verdict(f"no {root} found")
    torso = nodes_body[paths[root]].mean(0)
    t_torso = _mid(template.gc(root).place)
    for g in template.gcs:
        if g.name == root or g.name not in paths:
            continue
        p, pl = nodes_body[paths[g.name]], g.place
        down = pl["start"][2] - pl["end"][2] >= LEG_DOWN
        side = _mid(pl)[0] - t_torso[0]
        if not down and abs(side) >= END_FRONT and np.sign(p.mean(0)[0] - torso[0]) != np.sign(side):
            where = "front" if side > 0 else "back"
            return Verdict(f"ends: {g.name} is not at the {where} of the {root} (head and tail "
                           "at opposite ends, the neck toward the head)")
        if down and p[-1][2] >= torso[2]:
            return Verdict(f"ground: {g.name} does not reach down below the {root}")
    failed = _thickness(template, paths, radius, root, t_torso)
    if failed:
        return Verdict(failed)
    for g in template.gcs:
        s = g.symmetric
        if s is None or g.name not in paths or s not in paths or _mid(g.place)[1] < SIDE:
            continue
        left, right = nodes_body[paths[g.name]], nodes_body[paths[s]]
        if left.mean(0)[1] <= right.mean(0)[1]:
            return Verdict(f"sides: {g.name} lies right of {s} (left and right swapped)")
        la, lb = (float(np.linalg.norm(np.diff(x, axis=0), axis=1).sum()) for x in (left, right))
        if max(la, lb) > MIRROR_RATIO * max(min(la, lb), 1e-9):
            return Verdict(f"mirror: {g.name} and {s} differ in length {la / max(lb, 1e-9):.1f}x "
                           "(not mirror images)")
    return Verdict(None)


def _thickness(template: Template, paths: dict, radius: np.ndarray, root: str,
               t_torso: np.ndarray) -> str | None:
    """The thickness check (module docstring): None when it passes."""
    ends = [g for g in template.gcs if g.name != root and g.name in paths
            and g.place["start"][2] - g.place["end"][2] < LEG_DOWN
            and abs(_mid(g.place)[0] - t_torso[0]) >= END_FRONT]
    for a in ends:
        for b in ends:
            opposite = (_mid(a.place)[0] - t_torso[0]) * (_mid(b.place)[0] - t_torso[0]) < 0
            if opposite and a.place["radius"] >= THICK_RATIO * b.place["radius"] and \
                    _outer(radius, paths[a.name]) < THINNER * _outer(radius, paths[b.name]):
                return (f"thickness: {a.name} is not thicker than {b.name} (the template's is "
                        f"{a.place['radius'] / b.place['radius']:.1f}x: front and back swapped?)")
    return None


def _outer(radius: np.ndarray, path: np.ndarray) -> float:
    """The median inscribed radius over a path's outer half (its inner end lies in the body)."""
    return float(np.median(radius[path[len(path) // 2:]]))
