"""Legs named front or hind by where they leave the body (docs/transfer.md, "How a template
is placed", step 2).

The correspondence names legs by where their feet are. A gathered gallop lands the hind feet
under the belly, in front of where the front feet reach, and a front foot pressed against a
hind leg merges into it (no free end of its own): by the feet, the hind legs take the front
legs' names. Where a leg's path starts, where it leaves the body at the shoulder or the hip,
does not move with the feet.
"""
from __future__ import annotations

import numpy as np

from ngc_gen.data.autogc.template import Template

LEG_DOWN = 0.5     # a limb whose place ends this much lower than it starts is a leg
START_SLACK = 0.1  # a front leg's path may start this far (body units) behind its hind
                   # partner's (a skeleton joining a pair mid-body; a gallop's swapped pair: 0.3)


def reaches_down(place: dict) -> bool:
    """A template part whose place ends LEG_DOWN (body units) lower than it starts: a leg."""
    return float(place["start"][2]) - float(place["end"][2]) >= LEG_DOWN


def _legs_by_start(template: Template, nodes_body: np.ndarray,
                   assign: dict[str, int], paths: dict) -> dict[str, int]:
    """The legs named front or hind by where their paths start (where each leaves the body:
    shoulder or hip, front to back in body x), not where their feet are: a gathered gallop's
    hind feet land under the belly, in front of the front feet, and a front foot pressed
    against a hind leg merges into it (no free end of its own). On one side, a front leg
    starting more than START_SLACK behind its hind partner swaps with it; a leg alone on its
    side takes the name (front or hind) of the other side's leg whose start is nearer its own.
    nodes_body (N, 3): the tree's nodes in the body frame; paths: each matched GC's node
    indices, root side first."""
    root = template.gc(template.root)
    mid = _mid_x(root.place)
    legs = [g for g in template.gcs if g.parent == root.name and g.symmetric is not None and
            reaches_down(g.place)]
    front = [g.name for g in legs if _mid_x(g.place) > mid]
    # sides: front leg -> its hind leg on the same side
    pair = {f: next(h.name for h in legs if h.name not in front and
                    np.sign(h.place["end"][1]) == np.sign(template.gc(f).place["end"][1]))
            for f in front}
    start = {g.name: float(nodes_body[paths[g.name][0]][0]) for g in legs
             if g.name in assign and g.name in paths}
    out = dict(assign)
    for f, h in pair.items():
        if f in start and h in start and start[f] < start[h] - START_SLACK:
            out[f], out[h] = assign[h], assign[f]
            start[f], start[h] = start[h], start[f]
    for f, h in pair.items():
        other = [(g, pair[g]) for g in pair if g != f]
        if (f in start) == (h in start) or not other:
            continue
        of, oh = other[0]
        if of not in start or oh not in start:
            continue
        alone = f if f in start else h
        nearer_front = abs(start[alone] - start[of]) < abs(start[alone] - start[oh])
        want = f if nearer_front else h
        if want != alone:
            out[want] = out.pop(alone)
    return out


def _mid_x(place: dict) -> float:
    return float(place["start"][0] + place["end"][0]) / 2.0


