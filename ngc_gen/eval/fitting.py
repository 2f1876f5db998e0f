"""Fitting (reconstruction) metrics, paper Table 1 (Sec. 4.1).

Conventions (distances in the meshes' own units, i.e. the normalised frame of the data):

- ``cd``: Chamfer distance, DeepSDF convention: 30k surface points on each mesh, squared
  nearest-neighbour distances, mean in each direction, the two means **summed**.
- ``hd``: Hausdorff distance, symmetric: max over both directions of the nearest-neighbour
  distance, on the same 30k samples.
- ``emd``: Earth mover's distance: exact optimal assignment (``linear_sum_assignment``) between
  2048 points of each mesh under Euclidean cost, the **mean** matched distance.
- ``cd_l1``: Chamfer-L1: unsquared nearest-neighbour distances, mean each way, the two means
  **averaged** (half their sum).
- ``fscore``: F-score at tau (default 0.01): precision = fraction of predicted samples within
  tau of the ground-truth *surface*, recall the converse, F = 2PR/(P+R) (libigl's exact
  point-mesh distance). ``fscore_samples``: the same against the other mesh's 30k samples, the
  usual shortcut; it measures sample spacing as well: where that exceeds tau (a creature's 30k
  samples are ~0.01 apart) the exact surface itself scores 0.89.
- ``normal_consistency``: mean |cos| between each sample's face normal and the normal of the
  nearest face of the other mesh, mean each way, the two averaged (orientation-agnostic);
  ``nc_samples``: with the nearest sample's normal instead.
- ``mesh_chamfer``: the ``cd`` convention (30k points on each mesh, squared distances, means
  summed) with each point's distance to the other mesh's *surface* instead of to its samples:
  ``cd`` between two samplings of one surface is not 0 (~1e-4 at 30k points, and one face more
  or less moves every later sample), ``mesh_chamfer`` of equal surfaces is 0. It compares two
  extractions of one field (sparse vs reference), not a reconstruction with its ground truth.
- ``fragments`` / ``gt_fragments``: connected components (faces joined through shared vertices,
  coincident vertices merged) with fewer than ``fragment_fraction`` (default 1%) of the mesh's
  faces: the stray bits a fit leaves that the distances average away.

Both meshes are sampled with the same seed (see ``sampling``), so all numbers are deterministic.
The samples of ``reconstruction_metrics`` lie on the boundary of the solid each mesh bounds
(``sample_boundary``): faces of a closed piece inside another piece are not part of any surface
a signed distance field can have, so they are not scored.
"""

from __future__ import annotations

import math

import igl
import numpy as np
import trimesh
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from ngc_gen.eval.point_samples import is_empty, sample_boundary


def _check_points(p: np.ndarray, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise ValueError(f"{name} must be a non-empty (n, 3) array, got shape {p.shape}")
    return p


def nearest(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every point of src (n, 3): distance to and index of its nearest point in dst (m, 3)."""
    dist, idx = cKDTree(_check_points(dst, "dst")).query(_check_points(src, "src"), k=1)
    return dist, idx


def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Squared Chamfer: mean_a min_b |a-b|^2 + mean_b min_a |a-b|^2 (sum of the two means)."""
    d_ab, _ = nearest(a, b)
    d_ba, _ = nearest(b, a)
    return float(np.mean(d_ab ** 2) + np.mean(d_ba ** 2))


def chamfer_l1(a: np.ndarray, b: np.ndarray) -> float:
    """Chamfer-L1: (mean_a min_b |a-b| + mean_b min_a |a-b|) / 2 (average of the two means)."""
    d_ab, _ = nearest(a, b)
    d_ba, _ = nearest(b, a)
    return float(0.5 * (np.mean(d_ab) + np.mean(d_ba)))


def hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Hausdorff: max(max_a min_b |a-b|, max_b min_a |a-b|)."""
    d_ab, _ = nearest(a, b)
    d_ba, _ = nearest(b, a)
    return float(max(d_ab.max(), d_ba.max()))


def emd(a: np.ndarray, b: np.ndarray) -> float:
    """Exact EMD between equal-size point sets: mean Euclidean distance under the optimal
    one-to-one assignment (``scipy.optimize.linear_sum_assignment``). O(n^3); n ~ 2048."""
    a, b = _check_points(a, "a"), _check_points(b, "b")
    if len(a) != len(b):
        raise ValueError(f"emd needs equal point counts, got {len(a)} and {len(b)}")
    cost = cdist(a, b)
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].mean())


def fscore(a: np.ndarray, b: np.ndarray, tau: float = 0.01) -> float:
    """F-score at tau with a = prediction, b = ground truth: precision = frac(a within tau of b),
    recall = frac(b within tau of a) (strict '<'), F = 2PR/(P+R), 0 when P+R = 0."""
    d_ab, _ = nearest(a, b)
    d_ba, _ = nearest(b, a)
    p, r = float(np.mean(d_ab < tau)), float(np.mean(d_ba < tau))
    return 0.0 if p + r == 0.0 else 2.0 * p * r / (p + r)


def normal_consistency(a: np.ndarray, na: np.ndarray, b: np.ndarray, nb: np.ndarray) -> float:
    """Mean |cos| between each point's unit normal and its nearest neighbour's normal in the other
    set; mean each way, the two averaged. 1 = perfectly consistent, orientation ignored."""
    _, i_ab = nearest(a, b)
    _, i_ba = nearest(b, a)
    c_ab = np.abs(np.einsum("nd,nd->n", na, nb[i_ab]))
    c_ba = np.abs(np.einsum("nd,nd->n", nb, na[i_ba]))
    return float(0.5 * (c_ab.mean() + c_ba.mean()))


def _segment_distance2(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    lam = np.clip(np.einsum("nkd,nkd->nk", p - a, ab) / np.maximum(
        np.einsum("nkd,nkd->nk", ab, ab), 1e-300), 0.0, 1.0)
    return np.sum((a + lam[..., None] * ab - p) ** 2, -1)


def point_triangle_distance2(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Squared distance of points p (n, k, 3) to triangles tri (n, k, 3, 3), exact: the
    plane distance where the projection falls inside, else the nearest edge."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    nrm = np.cross(b - a, c - a)
    nn = np.maximum(np.einsum("nkd,nkd->nk", nrm, nrm), 1e-300)
    h = np.einsum("nkd,nkd->nk", p - a, nrm)
    q = p - (h / nn)[..., None] * nrm                       # projection onto the plane
    inside = np.ones(h.shape, dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("nkd,nkd->nk", np.cross(v - u, q - u), nrm) >= 0.0
    edges = np.minimum(np.minimum(_segment_distance2(p, a, b), _segment_distance2(p, b, c)),
                       _segment_distance2(p, c, a))
    return np.where(inside, h * h / nn, edges)


def point_mesh_distance(points: np.ndarray, mesh: trimesh.Trimesh, k: int = 16) -> np.ndarray:
    """(n,) exact distance of each point to the surface of `mesh`: the nearest of the faces
    whose centroids are nearest, widened until no other face can be nearer (a face whose
    centroid is farther than the best distance plus the largest centroid-vertex distance)."""
    points = _check_points(points, "points")
    tris = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces)]
    cen = tris.mean(1)
    reach = np.sqrt(((tris - cen[:, None]) ** 2).sum(-1)).max()
    tree = cKDTree(cen)
    out = np.empty(len(points))
    todo = np.arange(len(points))
    while len(todo):
        kk = min(k, len(cen))
        dc, idx = tree.query(points[todo], k=kk)
        dc, idx = dc.reshape(len(todo), kk), idx.reshape(len(todo), kk)
        d = np.sqrt(point_triangle_distance2(
            np.broadcast_to(points[todo][:, None], (len(todo), kk, 3)), tris[idx]).min(1))
        done = (kk == len(cen)) | (dc[:, -1] > d + reach)
        out[todo[done]] = d[done]
        todo, k = todo[~done], 4 * k
    return out


def mesh_chamfer(a: trimesh.Trimesh, b: trimesh.Trimesh, n: int = 30_000, seed: int = 0) -> float:
    """Squared Chamfer between the surfaces of two meshes (module docstring, ``mesh_chamfer``):
    n points on each (``sample_surface``, same seed), squared distance to the other mesh's
    surface, mean each way, the two means summed; a point on a face the other mesh also has
    (the same three vertex positions) is at distance 0 without a search."""
    def face_keys(m):
        v = np.ascontiguousarray(np.asarray(m.vertices, dtype=np.float64)[np.asarray(m.faces)]
                                 .reshape(len(m.faces), 9))
        return v.view(np.dtype((np.void, v.dtype.itemsize * 9))).ravel()

    ka, kb = face_keys(a), face_keys(b)
    total = 0.0
    for src, dst, shared in ((a, b, np.isin(ka, kb)), (b, a, np.isin(kb, ka))):
        pts, face = trimesh.sample.sample_surface(src, int(n), seed=int(seed))
        d2 = np.zeros(len(pts))
        off = ~shared[face]
        if off.any():
            d2[off] = point_mesh_distance(pts[off], dst) ** 2
        total += float(d2.mean())
    return total


def face_components(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) int64 connected-component label of each face, labels 0..C-1 (faces joined through
    shared vertices; vertices at the same position count as one, so an unmerged triangle soup
    is not split)."""
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if len(faces) == 0:
        return np.zeros(0, dtype=np.int64)
    _, vid = np.unique(np.asarray(mesh.vertices), axis=0, return_inverse=True)
    f = vid.reshape(-1)[faces]
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
    labels = trimesh.graph.connected_component_labels(edges, node_count=int(vid.max()) + 1)
    _, out = np.unique(labels[f[:, 0]], return_inverse=True)
    return out.reshape(-1).astype(np.int64)


def component_sizes(mesh: trimesh.Trimesh) -> np.ndarray:
    """Face count of each connected component (``face_components``), largest first."""
    labels = face_components(mesh)
    return np.sort(np.bincount(labels))[::-1] if len(labels) else np.zeros(0, dtype=np.int64)


def fragments(mesh: trimesh.Trimesh, fraction: float = 0.01) -> int:
    """Number of connected components with fewer than `fraction` of the mesh's faces."""
    sizes = component_sizes(mesh)
    return int((sizes < fraction * sizes.sum()).sum())


def _to_surface(points: np.ndarray, mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """Exact distance of each point to the mesh's surface and the index of the nearest face
    (libigl's AABB tree)."""
    d2, face, _ = igl.point_mesh_squared_distance(
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64))
    return np.sqrt(np.maximum(d2, 0.0)), face


def _f(d_pred_to_gt: np.ndarray, d_gt_to_pred: np.ndarray, tau: float) -> float:
    prec, rec = float(np.mean(d_pred_to_gt < tau)), float(np.mean(d_gt_to_pred < tau))
    return 0.0 if prec + rec == 0.0 else 2.0 * prec * rec / (prec + rec)


def reconstruction_metrics(pred_mesh: trimesh.Trimesh, gt_mesh: trimesh.Trimesh, seed: int = 0,
                           n_chamfer: int = 30_000, n_emd: int = 2048,
                           fscore_tau: float = 0.01, fragment_fraction: float = 0.01) -> dict:
    """All fitting metrics of pred_mesh against gt_mesh (conventions in the module docstring).

    Keys: cd, hd, emd, cd_l1, fscore, fscore_samples, normal_consistency, nc_samples (pred vs
    gt), volume, area, watertight,
    fragments (pred), gt_volume, gt_area, gt_watertight, gt_fragments, empty. Volumes are
    trimesh's ``mesh.volume`` and are meaningful only when the mesh is watertight (see the ``watertight`` flags).
    An empty prediction (no faces / zero area) does not raise: distances are inf,
    fscore 0.0, normal_consistency nan, volume and area 0.0, and ``empty`` is True.
    An empty ground truth raises ValueError. Plain Python floats throughout.
    """
    if is_empty(gt_mesh):
        raise ValueError("ground-truth mesh is empty (no faces or zero area)")
    out = {"gt_volume": float(gt_mesh.volume), "gt_area": float(gt_mesh.area),
           "gt_watertight": bool(gt_mesh.is_watertight),
           "gt_fragments": fragments(gt_mesh, fragment_fraction)}
    if is_empty(pred_mesh):
        inf = math.inf
        out.update(cd=inf, hd=inf, emd=inf, cd_l1=inf, fscore=0.0, fscore_samples=0.0,
                   normal_consistency=math.nan, nc_samples=math.nan,
                   volume=0.0, area=0.0, watertight=False, fragments=0, empty=True)
        return out
    p, pn = sample_boundary(pred_mesh, n_chamfer, seed)
    g, gn = sample_boundary(gt_mesh, n_chamfer, seed)
    d_pg, i_pg = nearest(p, g)
    d_gp, i_gp = nearest(g, p)
    s_pg, f_pg = _to_surface(p, gt_mesh)
    s_gp, f_gp = _to_surface(g, pred_mesh)
    out.update(
        cd=float(np.mean(d_pg ** 2) + np.mean(d_gp ** 2)),
        hd=float(max(d_pg.max(), d_gp.max())),
        emd=emd(sample_boundary(pred_mesh, n_emd, seed)[0],
                sample_boundary(gt_mesh, n_emd, seed)[0]),
        cd_l1=float(0.5 * (d_pg.mean() + d_gp.mean())),
        fscore=_f(s_pg, s_gp, fscore_tau),
        fscore_samples=_f(d_pg, d_gp, fscore_tau),
        normal_consistency=float(0.5 * (
            np.abs(np.einsum("nd,nd->n", pn, gt_mesh.face_normals[f_pg])).mean()
            + np.abs(np.einsum("nd,nd->n", gn, pred_mesh.face_normals[f_gp])).mean())),
        nc_samples=float(0.5 * (np.abs(np.einsum("nd,nd->n", pn, gn[i_pg])).mean()
                                + np.abs(np.einsum("nd,nd->n", gn, pn[i_gp])).mean())),
        volume=float(pred_mesh.volume), area=float(pred_mesh.area),
        watertight=bool(pred_mesh.is_watertight),
        fragments=fragments(pred_mesh, fragment_fraction), empty=False,
    )
    return out
