"""The body frame (world <-> body coordinates) and the skeleton tree a template is matched onto."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ngc_gen.data.autogc.branches import branch_graph, junction_key
from ngc_gen.data.autogc.orient import Orientation
from ngc_gen.data.autogc.template import Template
from ngc_gen.geometry import GeneralizedCylinder


@dataclass(frozen=True)
class BodyFrame:
    """World <-> body coordinates: body = (world @ R.T - center) / half, R rows front, left,
    up; center, half (3,): the bounding box of the surface in (front, left, up)."""

    R: np.ndarray
    center: np.ndarray
    half: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, orientation: Orientation) -> "BodyFrame":
        R = orientation.matrix
        B = points @ R.T
        lo, hi = B.min(0), B.max(0)
        return cls(R, (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 1e-9))

    def to_body(self, p: np.ndarray) -> np.ndarray:
        return (np.asarray(p) @ self.R.T - self.center) / self.half

    def to_world(self, b: np.ndarray) -> np.ndarray:
        return (np.asarray(b) * self.half + self.center) @ self.R

    def length(self, b_vec: np.ndarray) -> float:
        """World length of a body-frame vector (3,)."""
        return float(np.linalg.norm(np.asarray(b_vec) * self.half))


def extreme_points(points: np.ndarray) -> np.ndarray:
    """The points (N, 3) that can be extreme along some direction (the convex hull's
    vertices), for ``BodyFrame.of`` in many orientations: the same bounding box from a few
    hundred points instead of every surface sample; all of them when there is no hull (flat)."""
    from scipy.spatial import ConvexHull, QhullError

    P = np.asarray(points, dtype=np.float64)
    try:
        return P[ConvexHull(P).vertices]
    except (QhullError, ValueError):
        return P


def template_rotation(template: Template, orientation: Orientation) -> np.ndarray:
    """(3, 3) M turning a direction in the template's frame into the mesh's: M @ v."""
    tf = Orientation(template.up, template.front)
    return orientation.matrix.T @ tf.matrix


@dataclass
class Tree:
    """nodes (N, 3), radius (N,), graph: (N, N) sparse edge lengths, main (N,) bool: the body's
    piece, branch_of (N,): the branch each node came from, branch_dir (B, 3): unit direction of
    each branch toward its free end (zero for inner branches), branch_r (B,) mean radius,
    branch_root (B, 3): where an end branch leaves the rest (its junction end)."""

    nodes: np.ndarray
    radius: np.ndarray
    graph: object
    main: np.ndarray
    branch_of: np.ndarray
    branch_dir: np.ndarray
    branch_r: np.ndarray
    branch_root: np.ndarray

    @property
    def degree(self) -> np.ndarray:
        return np.diff(self.graph.indptr)


def skeleton_tree(sk, radius: np.ndarray, min_length: float, max_branches: int) -> Tree:
    """The branch tree of a proxy skeleton `sk` (local thickness `radius` per node), spurs
    shorter than min_length x their thickness pruned."""
    branches = branch_graph(sk.nodes, sk.edges, radius, min_length, max_branches)
    key_id: dict = {}
    pts, rad, owner, edges = [], [], [], []
    dirs, mean_r, roots = [], [], []
    n = 0
    for b, br in enumerate(branches):
        ids = []
        for k, (p, r) in enumerate(zip(br.points, br.radius)):
            end = k == 0 or k == len(br.points) - 1
            key = junction_key(p) if end else None
            if key is not None and key in key_id:
                ids.append(key_id[key])
                continue
            pts.append(p)
            rad.append(r)
            owner.append(b)
            if key is not None:
                key_id[key] = n
            ids.append(n)
            n += 1
        edges += list(zip(ids[:-1], ids[1:]))
        d = np.zeros(3)
        if br.junction[0] != br.junction[1] and len(br.points) > 1:
            d = br.points[-1] - br.points[0] if br.junction[0] else br.points[0] - br.points[-1]
            d = d / max(np.linalg.norm(d), 1e-12)
        dirs.append(d)
        roots.append(br.points[0] if br.junction[0] else br.points[-1])
        mean_r.append(float(np.mean(br.radius)))
    P = np.asarray(pts, dtype=np.float64)
    E = np.asarray([e for e in edges if e[0] != e[1]], dtype=np.int64).reshape(-1, 2)
    w = np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1) + 1e-9
    G = coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                   shape=(n, n)).tocsr()
    _, comp = connected_components(G, directed=False)
    seg = np.zeros(n)
    np.add.at(seg, E[:, 0], w * np.asarray(rad)[E[:, 0]] ** 2)
    weight = np.bincount(comp, weights=seg + np.asarray(rad) ** 3)
    main = comp == int(np.argmax(weight))
    return Tree(P, np.asarray(rad), G, main, np.asarray(owner), np.asarray(dirs),
                np.asarray(mean_r), np.asarray(roots, dtype=np.float64).reshape(-1, 3))


def surface_share(tree: Tree, samples: np.ndarray) -> np.ndarray:
    """(N,) the share of area-uniform surface `samples` (S, 3) nearest each tree node: weighed
    by the labels of a match, the surface each GC holds (``verify``)."""
    from scipy.spatial import cKDTree

    near = cKDTree(tree.nodes).query(samples, k=1)[1]
    return np.bincount(near, minlength=len(tree.nodes)) / max(len(samples), 1)


def _curve_points(gc: GeneralizedCylinder, n: int = 64) -> np.ndarray:
    return np.asarray(gc.to_world(np.stack([np.linspace(-1, 1, n), np.zeros(n), np.zeros(n)], 1)))
