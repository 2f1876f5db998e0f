"""Where a leg's own surface begins (docs/transfer.md, "How a template is placed", step 4).

A curve skeleton's leg branch leaves the body at the belly line, but a rig's leg starts at its
hip or shoulder joint, high in the body, and the flank over that joint (the thigh, the
shoulder blade) moves with the leg. Owned by the nearest skeleton node, that flank is the
torso's (the torso's path runs nearer than the leg's, which ends below it), and the leg's GC,
fitted to its own surface, holds only the leg below the belly line: against a rig's leg,
barely half of its surface.

``joint_columns`` gives each matched leg a column of points straight up (body up) from where
its branch becomes the leg (its path's first node as thin as the leg) to the height its
template part starts (the rig's joint, body units), at the leg's own front-back and side
position; surface samples nearest that column belong to the leg (``Placing.owner``): the flank
on its own side around its joint, not the belly's middle nor the back's top.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ngc_gen.data.autogc.template import Template

from .leg_order import reaches_down
from .tree import BodyFrame, Tree

THIN = 1.25  # a leg's path is the leg from its first node at most this x the median radius
             # of its lower half (as the limb's first nodes inside its parent are trimmed)


def _is_leg(template: Template, name: str) -> bool:
    """A part on the root whose template place reaches down (`reaches_down`)."""
    tgc = template.gc(name)
    if tgc.parent is None or template.gc(tgc.parent).parent is not None:
        return False
    return reaches_down(tgc.place)


def joint_columns(template: Template, tree: Tree, body: BodyFrame,
                  paths: dict) -> tuple[np.ndarray, np.ndarray]:
    """(points (K, 3) in world, the template GC index of each (K,)): per matched leg, points
    one tree edge apart (median) from its path's first thin node straight up to its template
    start's height, the lowest left out (module docstring). Empty when no leg starts below
    its joint."""
    names = template.names
    G = tree.graph.tocoo()
    step = float(np.median(G.data)) if G.nnz else 0.0
    pts, labels = [], []
    for name, p in paths.items():
        if not _is_leg(template, name) or len(p) < 2 or step <= 0.0:
            continue
        R = tree.radius[np.asarray(p)]
        k = int(np.argmax(R <= THIN * float(np.median(R[len(R) // 2:]))))
        base = body.to_body(tree.nodes[p[k]])
        top = float(template.gc(name).place["start"][2])
        n = int(np.ceil((top - base[2]) * body.half[2] / step))
        if n < 1:
            continue
        col = np.repeat(base[None], n, axis=0)
        col[:, 2] = np.linspace(base[2], top, n + 1)[1:]
        pts.append(body.to_world(col))
        labels += [names.index(name)] * n
    if not pts:
        return np.zeros((0, 3)), np.zeros(0, dtype=int)
    return np.concatenate(pts), np.asarray(labels, dtype=int)


def owner_of(surface: np.ndarray, template: Template, tree: Tree, labels: np.ndarray,
             body: BodyFrame, paths: dict) -> np.ndarray:
    """(S,) the template GC index of every surface sample (S, 3): its nearest tree node's
    (`labels` (N,)), or a leg's when the sample is the leg's parent's (the torso's: not the
    tail's root nor the neck's base) and the leg's column (``joint_columns``) is nearer."""
    d0, i0 = cKDTree(tree.nodes).query(surface, k=1)
    owner = labels[i0]
    pts, col = joint_columns(template, tree, body, paths)
    if not len(pts):
        return owner
    d1, i1 = cKDTree(pts).query(surface, k=1)
    names = template.names
    parent = np.array([names.index(template.gc(names[g]).parent) for g in col])
    take = (d1 < d0) & (owner == parent[i1])
    owner[take] = col[i1[take]]
    return owner
