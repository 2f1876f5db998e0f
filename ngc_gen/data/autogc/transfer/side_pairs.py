"""Mirrored side branches on a chain's path: where a head starts (docs/transfer.md, "How a
template is placed", step 2).

Ears, horns and antlers rise out of a head in pairs, one left and one right of the mid-plane;
the template's lengths cut a neck from its head wherever the template's animals had it, and a
short-necked, long-snouted mesh (a rhino) puts that cut far past its ears. The junction where
such a pair leaves the chain is the head's start, wherever the lengths cut.
"""
from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.sparse.csgraph import dijkstra

from .tree import BodyFrame, Tree

PAIR_SIDE = 0.2  # a side branch's free end this far (body units) left or right of the mid-plane


def paired_junction(tree: Tree, body: BodyFrame, own: list[int],
                    beyond: Callable[[np.ndarray], np.ndarray]) -> int | None:
    """The index on a chain's path `own` (junction -> tip) where the first pair of side
    branches has left it (a free end PAIR_SIDE left and one right of the mid-plane, both
    `beyond` (body frame tips -> bool) where the chain starts: not a pair of shoulder spurs,
    and above where they leave it: ears, horns and antlers rise from the skull, tusks hang
    from the mouth), None without one. Only side branches meeting the chain inside it count: what meets it at
    its first node is the rest of the body."""
    leaves = np.flatnonzero(tree.main & (tree.degree == 1))
    free = np.setdiff1d(leaves, own)
    if len(free) < 2:
        return None
    _, _, meet = dijkstra(tree.graph, indices=np.asarray(own), min_only=True,
                          return_predecessors=True)
    at = {int(n): i for i, n in enumerate(own)}
    k = np.array([at.get(int(m), 0) for m in meet[free]])
    tips = body.to_body(tree.nodes[free])
    rise = tips[:, 2] > body.to_body(tree.nodes[np.asarray(own)[k]])[:, 2]
    inside = (k > 0) & (k < len(own) - 1) & beyond(tips) & rise
    left = k[inside & (tips[:, 1] >= PAIR_SIDE)]
    right = k[inside & (tips[:, 1] <= -PAIR_SIDE)]
    if not len(left) or not len(right):
        return None
    return int(max(left.min(), right.min()))
