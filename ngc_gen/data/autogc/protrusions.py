"""Thin parts the curve skeleton missed (docs/autogc.md, second pass).

A mean-curvature-flow skeleton contracts a thin flat protrusion (a creature's ear on its head)
into the body it grows from, so no branch reaches it. Such a part shows on the surface: its
samples lie far from the skeleton relative to the thickness of the surface there. A surface
sample q with nearest skeleton node j is *far* when |q - x_j| > ``far`` x r_j (r_j: the node's
distance to the surface) and |q - x_j| > ``thin`` x w(q), where w(q) is the surface's own
half-thickness at q: the deepest point (distance transform of the closed proxy's inside voxels)
on the inward normal ray before it leaves the inside. A round or elliptic body keeps both ratios
near 1 (w is the body's radius); an ear on a head is a few times thinner than its distance to
the head's axis. The far samples are joined into
clusters (samples closer than ``link``); every cluster that sticks out of its anchor node's
ball by at least ``min_length`` of its own thickness becomes a new branch: a polyline of slice
centroids from the anchor's surface to the cluster's tip. Deterministic; one loop per cluster.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ngc_gen.data.autogc.branches import Branch

FAR = 1.5           # a sample is far from the skeleton past this x the node's thickness
THIN = 2.5          # ... and past this x the surface's own half-thickness there
MIN_SHARE = 0.002   # a cluster needs at least this share of the surface samples
THINNER = 0.5       # a protrusion is at most this x as thick as the body it grows from
ALONG = 0.77        # |cos| of the angle to the branch above which a cluster is its own end
ROOT = 0.6          # a protrusion starts this x the body's thickness from its anchor (inside the body)
N_SLICES = 6        # polyline nodes along a protrusion (slice centroids)


def half_thickness(points: np.ndarray, normals: np.ndarray, inside: np.ndarray, origin: np.ndarray,
                   h: float, max_steps: int = 24) -> np.ndarray:
    """(N,) the surface's half-thickness at points (N, 3) with unit normals (N, 3) of either
    orientation: along the ray q - s n (both signs of n, steps of h/2), the largest distance to
    the outside (voxels of ``inside`` (X, Y, Z), origin (3,), size h) before the ray leaves."""
    from scipy import ndimage

    edt = np.pad(ndimage.distance_transform_edt(inside) * h, 1)  # 0 outside the grid
    steps = 0.5 * h * np.arange(1, max_steps + 1)
    best = np.zeros(len(points))
    for sign in (1.0, -1.0):
        ray = points[:, None, :] - sign * steps[None, :, None] * normals[:, None, :]  # (N, K, 3)
        ijk = np.rint((ray - origin) / h).astype(np.int64) + 1
        ijk = np.clip(ijk, 0, np.array(edt.shape) - 1)
        val = edt[ijk[..., 0], ijk[..., 1], ijk[..., 2]]  # (N, K)
        alive = np.cumprod(val > 0, axis=1).astype(bool)
        best = np.maximum(best, np.where(alive, val, 0.0).max(axis=1))
    return np.maximum(best, h)


def protrusion_branches(surface: np.ndarray, nodes: np.ndarray, radius: np.ndarray,
                        node_component: np.ndarray, link: float, width: np.ndarray,
                        tangent: np.ndarray | None = None, body: np.ndarray | None = None,
                        min_length: float = 1.0, far: float = FAR,
                        thin: float = THIN, max_new: int = 8) -> list[Branch]:
    """New branches for the thin parts no skeleton node reaches.

    surface (S, 3) samples; nodes (M, 3) skeleton samples with radius (M,) (local thickness)
    and node_component (M,) (the skeleton piece each belongs to); link: samples closer than
    this are one cluster; width (S,): the surface's half-thickness at each sample; tip (M,)
    bool: nodes near a branch's free end, where a cluster is that branch's own unreached tip
    (its GC's cap grows over it), not a new part; body (M,): the thickness of the body each
    node belongs to (default: radius), which a protrusion must be thinner than: the body of its
    anchor node, or the thinner body most of its samples are nearest to. Clusters are taken largest first, and the
    far samples are measured again against each new branch (one thin part, one branch). At most ``max_new`` branches, the largest clusters first."""
    body = radius if body is None else body
    d, j = cKDTree(nodes).query(surface, k=1)
    is_far = (d > far * radius[j]) & (d > thin * width)
    idx = np.flatnonzero(is_far)
    if len(idx) < max(3, MIN_SHARE * len(surface)):
        return []
    pairs = cKDTree(surface[idx]).query_pairs(link, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(idx),) * 2)
    n_clusters, label = connected_components(adj, directed=False)
    sizes = np.bincount(label, minlength=n_clusters)
    surf_tree = cKDTree(surface)
    out = []
    for c in np.argsort(-sizes, kind="stable"):
        if sizes[c] < MIN_SHARE * len(surface) or len(out) >= max_new:
            break
        mine = idx[label == c]
        if out:  # samples a new branch already reaches are no longer far
            added = np.concatenate([b.points for b in out])
            dn = cKDTree(added).query(surface[mine], k=1)[0]
            mine = mine[~((dn < d[mine]) & (dn <= thin * width[mine]))]
            if len(mine) < MIN_SHARE * len(surface):
                continue
        q = surface[mine]
        ratio = d[mine] / radius[j[mine]]
        anchor = int(j[mine][np.argmin(ratio)])  # where the cluster meets the body
        a, r_a = nodes[anchor], radius[anchor]
        # the body it grows from: the anchor's, or the one most of its samples are nearest to
        # if thinner (a flat ear whose skeleton branch runs along it is that branch's, no new part)
        r_body = min(float(body[anchor]), float(np.median(body[j[mine]])))
        far_pt = q[np.argmax(np.linalg.norm(q - a, axis=1))]
        axis = (far_pt - a) / max(np.linalg.norm(far_pt - a), 1e-12)
        if tangent is not None and abs(float(axis @ tangent[anchor])) > ALONG:
            continue
        s = (q - a) @ axis
        edges = np.linspace(max(float(s.min()), r_a), float(s.max()), N_SLICES + 1)
        which = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, N_SLICES - 1)
        counts = np.bincount(which, minlength=N_SLICES)
        keep = counts > 0
        cent = np.stack([np.bincount(which, weights=q[:, k], minlength=N_SLICES) for k in range(3)], 1)
        cent = cent[keep] / counts[keep, None]
        # from the anchor's surface (the body's own radius along the axis) to the far end
        start = a + axis * ROOT * r_a
        pts = np.concatenate([start[None], cent[cent @ axis - a @ axis > ROOT * r_a], far_pt[None]])
        if len(pts) < 3:
            continue
        rad = np.maximum(surf_tree.query(pts, k=1)[0], 0.25 * link)
        own = float(np.median(rad))
        length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        if length < min_length * own or own > THINNER * r_body:  # too short, or the body's own end
            continue
        out.append(Branch(pts, rad, (False, False), int(node_component[anchor])))
    return out
