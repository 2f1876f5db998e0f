"""The branch graph of a curve skeleton (docs/autogc.md).

A skeleton graph becomes a list of branches, each an ordered polyline between two nodes that are
ends (degree 1) or junctions (degree >= 3), with degree-2 nodes merged into the branches:
1. a spanning forest (minimum total edge length) cuts cycles: the small ones voxel thinning
   leaves at junctions, and real loops (a torus), whose one long branch is later split;
2. repeat until nothing changes: prune the spur (an end branch at a junction) that is shortest
   relative to the local thickness at its junction, if it is shorter than
   ``min_length * thickness``; contract an inner branch (junction to junction) shorter than the
   thickness at its junctions into one junction (two legs that leave a torso at nearly the
   same place meet there);
3. while there are more than ``max_branches`` branches, prune the weakest spur anyway.
Graph work is done with scipy.sparse.csgraph; loops run over branches, never over points.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components, minimum_spanning_tree


@dataclass
class Branch:
    """points (P, 3) ordered polyline, radius (P,) local thickness along it; junction: whether
    its first / last node is a junction; component: the connected skeleton piece it belongs to."""

    points: np.ndarray
    radius: np.ndarray
    junction: tuple[bool, bool]
    component: int

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def _adjacency(n: int, edges: np.ndarray, weights: np.ndarray | None = None):
    w = np.ones(len(edges)) if weights is None else weights
    a = coo_matrix((np.r_[w, w], (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                   shape=(n, n))
    return a.tocsr()


def spanning_forest(nodes: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Edges (E', 2) of a minimum spanning forest (edge weight = length; ties broken by order)."""
    if len(edges) == 0:
        return edges.reshape(0, 2)
    length = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    w = length + 1e-12 * (1.0 + np.arange(len(edges)) / len(edges))  # no zero weights, no ties
    upper = coo_matrix((w, (edges[:, 0], edges[:, 1])), shape=(len(nodes),) * 2)
    mst = minimum_spanning_tree(upper).tocoo()
    return np.sort(np.stack([mst.row, mst.col], axis=1).astype(np.int64), axis=1)


def decompose(n: int, edges: np.ndarray, alive: np.ndarray | None = None) -> list[np.ndarray]:
    """Node paths (each ordered end to end) of a forest: maximal chains of degree-2 nodes with
    the end / junction node at each side; an isolated node that is ``alive`` (default: all) is
    a path of one."""
    deg = np.bincount(edges.ravel(), minlength=n) if len(edges) else np.zeros(n, dtype=np.int64)
    chain = deg == 2
    alive = np.ones(n, dtype=bool) if alive is None else alive
    paths = [np.array([i]) for i in np.flatnonzero((deg == 0) & alive)]
    # an edge between two non-chain nodes is a branch of its own
    direct = ~chain[edges[:, 0]] & ~chain[edges[:, 1]] if len(edges) else np.zeros(0, bool)
    paths += [e for e in edges[direct]]
    inner = chain[edges[:, 0]] & chain[edges[:, 1]] if len(edges) else np.zeros(0, bool)
    n_comp, label = connected_components(_adjacency(n, edges[inner]), directed=False)
    label = np.where(chain, label, -1)
    full = _adjacency(n, edges)
    for c in np.unique(label[chain]):
        members = np.flatnonzero(label == c)
        outer = np.unique(full[members].indices)
        outer = outer[~chain[outer]]
        sub = np.r_[members, outer]
        local = full[sub][:, sub]
        # start from an outer end (a path between two non-chain nodes), else a chain end
        start = 0 if len(outer) == 0 else len(members)
        if len(outer) == 0:
            start = int(np.flatnonzero(np.diff(local.indptr) < 2)[0])
        order = breadth_first_order(local, start, directed=False, return_predecessors=False)
        path = sub[order]
        if len(outer) == 2 and path[-1] != outer[1] and path[-1] != outer[0]:
            raise AssertionError("a chain must run between its two outer nodes")
        paths.append(path)
    return paths


def _length(nodes: np.ndarray, path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(nodes[path], axis=0), axis=1).sum())


def _protrusion(nodes: np.ndarray, radius: np.ndarray, path: np.ndarray) -> float:
    """How far a spur (path from its junction to its tip) sticks out of the junction's ball,
    in units of its own thickness there: (length - r_junction) / median r beyond the ball."""
    P = nodes[path]
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    r_j = radius[path[0]]
    beyond = np.linalg.norm(P - P[0], axis=1) > r_j
    own = float(np.median(radius[path][beyond])) if beyond.any() else float(radius[path[-1]])
    return (arc[-1] - r_j) / max(own, 1e-12)


def prune(nodes: np.ndarray, radius: np.ndarray, edges: np.ndarray, min_length: float,
          max_branches: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """Spur pruning and junction merging (module docstring, steps 2-3).

    Returns (nodes, radius, edges, paths) of the pruned forest; unused nodes stay in the
    arrays (paths index them)."""
    nodes, radius, edges = nodes.copy(), radius.copy(), edges.copy()
    n = len(nodes)
    alive = np.ones(n, dtype=bool)
    while True:
        paths = decompose(n, edges, alive)
        deg = np.bincount(edges.ravel(), minlength=n) if len(edges) else np.zeros(n, np.int64)
        spurs, inner = [], []
        for i, p in enumerate(paths):
            if len(p) < 2:
                continue
            d0, d1 = deg[p[0]], deg[p[-1]]
            if (d0 == 1) != (d1 == 1) and max(d0, d1) >= 3:
                j = p[0] if d0 >= 3 else p[-1]
                spurs.append((_protrusion(nodes, radius, p if d0 >= 3 else p[::-1]), i, j))
            elif d0 >= 3 and d1 >= 3:
                r = max(radius[p[0]], radius[p[-1]])
                inner.append((_length(nodes, p) / max(r, 1e-12), i))
        n_branches = sum(len(p) >= 2 for p in paths) + sum(len(p) == 1 and deg[p[0]] == 0 for p in paths)
        spurs.sort()
        inner.sort()
        if inner and inner[0][0] < 1.0:  # contract the shortest inner branch into one junction
            p = paths[inner[0][1]]
            keep = p[0]
            nodes[keep] = nodes[p].mean(axis=0)
            radius[keep] = radius[p].max()
            remap = np.arange(n)
            remap[p] = keep
            alive[p[1:]] = False
            e = np.sort(remap[edges], axis=1)
            edges = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
            continue
        if spurs and (spurs[0][0] < min_length or n_branches > max_branches):
            _, i, j = spurs[0]
            drop = np.setdiff1d(paths[i], [j])
            alive[drop] = False
            edges = edges[~np.isin(edges, drop).any(axis=1)]
            continue
        return nodes, radius, edges, paths


def branch_graph(nodes: np.ndarray, edges: np.ndarray, radius: np.ndarray, min_length: float,
                 max_branches: int) -> list[Branch]:
    """Branches of a skeleton graph (nodes (N, 3), edges (E, 2), local thickness radius (N,)).

    Deterministic: the same graph gives the same branches in the same order (by component,
    then by the paths' first node)."""
    forest = spanning_forest(nodes, edges)
    nodes, radius, forest, paths = prune(nodes, radius, forest, min_length, max_branches)
    n = len(nodes)
    _, comp = connected_components(_adjacency(n, forest), directed=False)
    deg = np.bincount(forest.ravel(), minlength=n) if len(forest) else np.zeros(n, np.int64)
    out = []
    for p in sorted(paths, key=lambda q: (comp[q[0]], min(q[0], q[-1]), max(q[0], q[-1]))):
        if len(p) > 1 and p[0] > p[-1]:
            p = p[::-1]
        out.append(Branch(nodes[p], radius[p], (bool(deg[p[0]] >= 3), bool(deg[p[-1]] >= 3)),
                          int(comp[p[0]])))
    return out


#: a junction's other branches may be at most this x as thick as the thinner of the two that
#: `pass_through` joins there
THROUGH_THIN = 0.5


def junction_key(p: np.ndarray) -> tuple:
    """A skeleton node's position (3,) as a hashable key: the branches that meet at a junction
    end on the same node, so their end points give the same key."""
    return tuple(np.round(p, 9))


def pass_through(branches: list[Branch]) -> tuple[list[Branch], dict]:
    """Join the two branches of a junction that only thin end branches leave besides them.

    The skeleton of a head on its neck with a snout and two ears has a junction where the ears
    leave: neck -> junction -> snout, which would cut the head in two GCs (the neck's, holding
    the back of the head, and the snout's). Where the two thickest branches at a junction are
    one end branch (a free end) and any other, and every other branch there is an end branch at
    most ``THROUGH_THIN`` x the thinner of the two, they become one branch through the
    junction. A branch is joined at most once (no chains). Thickness: mean local radius.
    -> (branches, {junction key: index of the branch that now passes through it})."""
    at: dict = {}
    for i, b in enumerate(branches):
        for side in (0, -1):
            if b.junction[side]:
                at.setdefault(junction_key(b.points[side]), []).append((i, side))
    free = [not (b.junction[0] and b.junction[1]) for b in branches]
    thick = [float(b.radius.mean()) for b in branches]
    used, joined, through = set(), [], {}
    for key in sorted(at):
        ends = sorted(at[key], key=lambda e: (-thick[e[0]], e[0]))
        if len(ends) < 3 or len({i for i, _ in ends}) != len(ends):
            continue
        (i, si), (j, sj), rest = ends[0], ends[1], ends[2:]
        if i in used or j in used or not (free[i] or free[j]):
            continue
        if not all(free[k] and thick[k] <= THROUGH_THIN * min(thick[i], thick[j]) for k, _ in rest):
            continue
        a, b = branches[i], branches[j]
        pa, ra = (a.points, a.radius) if si == -1 else (a.points[::-1], a.radius[::-1])
        pb, rb = (b.points, b.radius) if sj == 0 else (b.points[::-1], b.radius[::-1])
        ja = a.junction[0] if si == -1 else a.junction[1]
        jb = b.junction[1] if sj == 0 else b.junction[0]
        used |= {i, j}
        joined.append((key, Branch(np.concatenate([pa, pb[1:]]), np.concatenate([ra, rb[1:]]),
                                   (bool(ja), bool(jb)), a.component)))
    out = [b for i, b in enumerate(branches) if i not in used]
    for key, b in joined:
        through[key] = len(out)
        out.append(b)
    return out, through
