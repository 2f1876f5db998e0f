"""Junction measure: is a fit worse where GCs meet than elsewhere, and does it leave loose pieces?

NGC takes the minimum of per-GC networks, each trained only inside its own GC; where GCs
overlap, and at a GC's boundary inside another GC (where the minimum stops seeing that GC),
nothing makes the networks agree, and a seam (crease, ridge, step) can appear that the global
metrics average away. Conventions (distances in the meshes' own units):

- *Relative radius* of a point in a GC: rho = sqrt(max(|u| - 1, 0)^2 + a^2 + b^2) from its
  relative coordinates (u, a, b) (docs/gcs.md): rho <= 1 inside, 1 on the GC's boundary, in units
  of the GC's radii (and cap lengths past an end).
- *Junction* sample: at least two GCs have rho <= 1 + ``band``. That is the overlap of two GCs
  (``band`` = 0) grown by a band of relative width ``band`` around each GC boundary that lies
  inside another GC: a point just outside GC g but inside GC h (g's boundary inside the union),
  or just inside g near h's boundary. Every other sample is *elsewhere*.
- ``n_samples`` points on the fitted surface (``sample_surface``, deterministic); for each, its
  exact distance to the true surface and the angle (degrees, orientation ignored, in [0, 90])
  between its face's normal and the normal of the nearest true face. The true surface is the
  boundary of the solid the truth bounds: faces inside another closed piece (the ant's) are left
  out, as in ``sample_boundary`` (a face is kept when any of 4 points on it is on the boundary).
- ``junction_ratio_dist`` = mean distance on junction samples / mean distance elsewhere;
  ``junction_ratio_normal`` the same with the angle. 1: junctions no worse than the rest.
  None when either set is empty (one GC has no junction); 1 when both means are 0, inf when
  only the one elsewhere is. Distances and angles at rounding level (``ROUNDING``) count as 0.
- ``junction_ratio_dist_local`` / ``junction_ratio_normal_local``: the junction mean over the
  elsewhere error *of the GCs that meet there*: each junction sample's baseline is the mean of
  the elsewhere errors of its two GCs of least rho (a GC's elsewhere error: the mean over the
  elsewhere samples whose least-rho GC it is, the whole elsewhere mean when it has under
  ``MIN_OWNED``). The plain ratio compares a junction with the whole shape: on an animal the
  junctions (torso to neck and legs) are broad and smooth while elsewhere holds the hooves,
  ears and face, so even the exact SDF meshed at 256^3 scores 0.78-0.82 there, and a fit
  whose error is 20x the grid's is held to the grid's curvature mix. The local ratio asks
  whether a junction is worse than the parts that meet at it (the grid's own: 0.85-0.99 on
  the animals).
- ``extra_pieces``: the fit's pieces beyond the truth's. A fitted mesh is a level set, whose
  connected components (``face_components``) never intersect, so each is a piece. The truth's
  pieces are its components joined where they come closer than ``join`` (intersecting closed
  pieces, like the ant's, are one solid; gaps under a grid cell are not resolved by any fit).
  Each fitted piece is matched to the true piece its faces are nearest to (majority of up to 32
  faces per piece); on each true piece the largest fitted piece is its match and every other
  one is extra (a loose horn tip, a floater, a piece broken in two), unless it is cut off where
  the truth itself is finer than a grid resolves (``sliver_breaks``): at the true surface point
  nearest the middle of the cut, the truth is thinner than ``sliver`` (about a cell: the truth's
  own SDF meshed at 256^3 breaks the ant's knees, 1-3e-3 thick, and an antenna, 5.5e-3) or the
  outside is narrower than ``join``, or it lies on closed parts of the truth that no other
  fitted piece of its true piece reaches (two true parts counted as one piece, rightly kept
  apart: the ant's abdomen, 8.5e-3 from its waist). Components join by each one's vertices
  and surface samples against the others' exact surface, so a gap just under ``join`` joins
  every time (an edit elsewhere does not change the count).
"""

from __future__ import annotations

from typing import Sequence

import igl
import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ngc_gen.eval.fitting import _to_surface, face_components
from ngc_gen.eval.point_samples import is_empty, on_solid_boundary, sample_surface
from ngc_gen.geometry import GeneralizedCylinder

FACES_PER_PIECE = 32      # faces of each fitted piece that vote for its true piece
MAX_JOIN_SAMPLES = 400_000
FIGURES = ("junction_ratio_dist", "junction_ratio_normal", "junction_dist", "elsewhere_dist",
           "junction_normal_deg", "elsewhere_normal_deg", "junction_share",
           "junction_ratio_dist_local", "junction_ratio_normal_local")   # None-able
MIN_OWNED = 20            # elsewhere samples a GC needs for its own baseline in the local ratio
ROUNDING = 1e-9           # distances under this x the truth's box diagonal, and angles whose
                          # cosine is this close to 1, are 0 (float64 rounding, not error)


def relative_radius(points: np.ndarray, gcs: Sequence[GeneralizedCylinder],
                    reach: float) -> np.ndarray:
    """(G, N) rho of points (N, 3) in every GC (module docstring), exact up to rho = 1 + reach
    and inf beyond: only points inside a GC's box grown by reach x its largest radius or cap
    are solved for, the others cannot come that close."""
    points = np.asarray(points, dtype=np.float64)
    rho = np.full((len(gcs), len(points)), np.inf)
    for g, gc in enumerate(gcs):
        lo, hi = gc.bounds()
        pad = reach * max(*(r for k in gc.keys for r in k.radii), *gc.caps) * 1.01  # lerped radii
        cand = np.flatnonzero(((points >= lo - pad) & (points <= hi + pad)).all(axis=1))
        if len(cand) == 0:
            continue
        rel = np.asarray(gc.to_relative(points[cand]))
        rho[g, cand] = np.sqrt(GeneralizedCylinder.relative_measure(rel))
    return rho


def local_ratio(err: np.ndarray, rho: np.ndarray, junction: np.ndarray) -> float | None:
    """Mean error on junction samples over the mean of their baselines: the elsewhere error of
    the two GCs of least rho at each (module docstring); err (N,), rho (G, N), junction (N,)."""
    if not junction.any() or junction.all():
        return None
    owner = np.argmin(rho, axis=0)
    away = ~junction
    held = away & np.isfinite(rho.min(0))   # samples past every GC's reach own no GC
    n = np.bincount(owner[held], minlength=len(rho))
    total = np.bincount(owner[held], weights=err[held], minlength=len(rho))
    own = np.where(n >= MIN_OWNED, total / np.maximum(n, 1), err[away].mean())
    pair = np.argsort(rho[:, junction], axis=0)[:2]
    base = 0.5 * (own[pair[0]] + own[pair[1]])
    return _ratio(float(err[junction].mean()), float(base.mean()))


def junction_mask(points: np.ndarray, gcs: Sequence[GeneralizedCylinder],
                  band: float) -> np.ndarray:
    """(N,) bool: the point is a junction sample, at least two GCs have rho <= 1 + band."""
    if band < 0:
        raise ValueError(f"band must be >= 0 (a relative radius), got {band}")
    if len(gcs) < 2:
        return np.zeros(len(points), dtype=bool)
    return (relative_radius(points, gcs, band) <= 1.0 + band).sum(0) >= 2


def boundary_faces(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The mesh less the faces that lie wholly inside another closed piece (none of 4 points on
    the face, its centroid and the midpoints toward its corners, has the outside on a side);
    a mesh that is not watertight is returned as it is (its inside is not defined)."""
    if not mesh.is_watertight:
        return mesh
    tri = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces)]
    cen = tri.mean(1)
    pts = np.concatenate([cen[:, None], 0.5 * (cen[:, None] + tri)], 1)      # (F, 4, 3)
    nrm = np.repeat(np.asarray(mesh.face_normals, dtype=np.float64), 4, axis=0)
    keep = on_solid_boundary(mesh, pts.reshape(-1, 3), nrm).reshape(-1, 4).any(1)
    if keep.all():
        return mesh
    return trimesh.Trimesh(mesh.vertices, np.asarray(mesh.faces)[keep], process=False)


def solid_pieces(mesh: trimesh.Trimesh, join: float, seed: int = 0) -> tuple[np.ndarray, int]:
    """((F,) piece label of each face, piece count): connected components joined where they
    come closer than `join`: a component's vertices and surface samples (<= join / 2 apart on
    average) against the exact surface of the other components, so two pieces closer than
    `join` join whatever the samples' luck (an edit that moves other parts keeps the count)."""
    comp = face_components(mesh)
    n_comp = int(comp.max()) + 1 if len(comp) else 0
    if n_comp <= 1:
        return comp, n_comp
    n = int(np.clip(np.ceil(4.0 * float(mesh.area) / join ** 2), 10_000, MAX_JOIN_SAMPLES))
    points, face = trimesh.sample.sample_surface(mesh, n, seed=int(seed))
    lab = comp[face]
    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    F = np.asarray(mesh.faces, dtype=np.int64)
    a, b = [], []
    for c in range(n_comp):   # a loop over the components, never over points
        rest = np.flatnonzero(comp != c)
        mine = np.concatenate([V[np.unique(F[comp == c])], points[lab == c]])
        d2, near, _ = igl.point_mesh_squared_distance(mine, V, np.ascontiguousarray(F[rest]))
        close = np.unique(comp[rest[near[d2 < join * join]]])
        a.append(np.full(len(close), c))
        b.append(close)
    a, b = np.concatenate(a), np.concatenate(b)
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n_comp, n_comp))
    n_pieces, piece_of_comp = connected_components(graph, directed=False)
    return piece_of_comp[comp].astype(np.int64), int(n_pieces)


def extra_pieces(pred_mesh: trimesh.Trimesh, gt_mesh: trimesh.Trimesh, join: float,
                 sliver: float, seed: int = 0) -> dict:
    """{extra_pieces, pieces, gt_pieces, sliver_breaks} (module docstring): the fit's
    components matched to the truth's solid pieces by the nearest true face of up to
    FACES_PER_PIECE of their faces; the ones beyond a piece's largest that are not cut off at
    a sliver of the truth are extra."""
    gt_piece, n_gt = solid_pieces(gt_mesh, join, seed)
    comp = face_components(pred_mesh)
    n_pred = int(comp.max()) + 1 if len(comp) else 0
    if n_pred == 0:
        return {"extra_pieces": 0, "pieces": 0, "gt_pieces": n_gt, "sliver_breaks": 0}
    # up to FACES_PER_PIECE faces of each component, in a fixed random order
    order = np.random.default_rng(seed).permutation(len(comp))
    order = order[np.argsort(comp[order], kind="stable")]
    first = np.searchsorted(comp[order], np.arange(n_pred))
    rank = np.arange(len(order)) - first[comp[order]]
    voters = order[rank < FACES_PER_PIECE]
    cen = np.asarray(pred_mesh.vertices, dtype=np.float64)[np.asarray(pred_mesh.faces)[voters]]
    _, near = _to_surface(cen.mean(1), gt_mesh)
    gt_comp = face_components(gt_mesh)[near]          # each voter's true component
    votes = comp[voters] * n_gt + gt_piece[near]
    key, count = np.unique(votes, return_counts=True)
    best = np.lexsort((-count, key // n_gt))                 # per component, most votes first
    kc = key[best] // n_gt
    winner = key[best][np.r_[True, kc[1:] != kc[:-1]]] % n_gt
    # on each true piece the largest fitted piece is its match, every other one a candidate
    size = np.bincount(comp, minlength=n_pred)
    by_piece = np.lexsort((-size, winner))
    main = np.r_[True, winner[by_piece][1:] != winner[by_piece][:-1]]
    candidates = by_piece[~main]
    slivers = sum(_apart_as_true(comp[voters], gt_comp, c, winner)
                  or _broken_at_sliver(pred_mesh, comp, c, winner, gt_mesh, join, sliver)
                  for c in candidates)               # a loop over pieces, not points
    return {"extra_pieces": int(len(candidates) - slivers), "pieces": n_pred,
            "gt_pieces": n_gt, "sliver_breaks": int(slivers)}


def _apart_as_true(voter_piece: np.ndarray, voter_comp: np.ndarray, c: int,
                   winner: np.ndarray) -> bool:
    """True when fitted piece c lies on true components (closed parts of the truth) that no
    other fitted piece of its true piece reaches: the truth's own separate parts, counted as
    one piece because they come closer than `join`, which the fit keeps apart as they are
    (the ant's abdomen beside its waist). voter_piece, voter_comp: per voting face, its fitted
    piece and its nearest true face's component."""
    others = np.isin(voter_piece, np.flatnonzero(winner == winner[c])) & (voter_piece != c)
    mine = np.unique(voter_comp[voter_piece == c])
    return bool(len(mine)) and not np.isin(mine, voter_comp[others]).any()


def _broken_at_sliver(pred_mesh: trimesh.Trimesh, comp: np.ndarray, c: int, winner: np.ndarray,
                      gt_mesh: trimesh.Trimesh, join: float, sliver: float) -> bool:
    """True when fitted piece c is cut from the rest of its true piece where the truth itself
    is finer than the grid: from the true surface point nearest the middle of the gap between
    c and the other fitted pieces of the same true piece, the solid is thinner than `sliver`
    along the normal (a bridge no grid resolves: the truth's own SDF meshed at 256^3 breaks the
    ant's knees there) or the outside narrower than `join` (a gap between true parts that
    `join` counted as one piece, which a fit may rightly keep apart). A cut through a thick
    part, or a floater beside one, is neither."""
    V = np.asarray(pred_mesh.vertices, dtype=np.float64)
    F = np.asarray(pred_mesh.faces)
    others = np.flatnonzero(winner == winner[c])
    mine = np.unique(F[comp == c])
    rest = np.unique(F[np.isin(comp, others[others != c])])
    d, i = cKDTree(V[rest]).query(V[mine])
    k = int(np.argmin(d))
    gap = 0.5 * (V[mine[k]] + V[rest[i[k]]])
    q, face = _closest_point(gap, gt_mesh)
    inward, outward = _crossing(gt_mesh, q, face)
    return inward < sliver or outward < join


def _closest_point(p: np.ndarray, mesh: trimesh.Trimesh) -> tuple[np.ndarray, int]:
    _, face, q = igl.point_mesh_squared_distance(
        np.ascontiguousarray(p[None], dtype=np.float64),
        np.ascontiguousarray(mesh.vertices, dtype=np.float64),
        np.ascontiguousarray(mesh.faces, dtype=np.int64))
    return q[0], int(face[0])


def _crossing(mesh: trimesh.Trimesh, q: np.ndarray, face: int) -> tuple[float, float]:
    """(inward, outward): distances from surface point q (on `face`) along the face's normal,
    into the solid and out of it, to the next face crossed (libigl's ray casting); inward is
    the side whose winding number is above 1/2; inf where no face is crossed."""
    n = np.asarray(mesh.face_normals[face], dtype=np.float64)
    V = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    Fa = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    eps = 1e-6 * float(np.linalg.norm(np.ptp(V, axis=0)))
    w = igl.fast_winding_number(V, Fa, (q - 100 * eps * n)[None])[0]
    inward = -n if abs(w) > 0.5 else n
    out = []
    for ray in (inward, -inward):
        hits = igl.ray_mesh_intersect(np.ascontiguousarray(q, dtype=np.float64),
                                      np.ascontiguousarray(ray), V, Fa) or []
        t = [h[1] for h in hits if h[0] != face and h[1] > eps]
        out.append(float(min(t)) if t else float("inf"))
    return out[0], out[1]


def _ratio(num: float | None, den: float | None) -> float | None:
    if num is None or den is None:
        return None
    if den == 0.0:
        return 1.0 if num == 0.0 else float("inf")
    return float(num / den)


def surface_errors(pred_mesh: trimesh.Trimesh, gt_mesh: trimesh.Trimesh, n_samples: int,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (n, 3) on the fitted surface, their distance to the true solid's boundary (n,),
    the angle in degrees between their normals (n,)): the per-sample errors both figures
    average (module docstring; rounding-level errors are 0)."""
    points, normals = sample_surface(pred_mesh, n_samples, seed)
    truth = boundary_faces(gt_mesh)
    dist, face = _to_surface(points, truth)
    cos = np.abs(np.einsum("nd,nd->n", normals, np.asarray(truth.face_normals)[face]))
    angle = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    # rounding is no error: a fit equal to the truth has ratio 1, not a ratio of rounding noise
    dist[dist < ROUNDING * float(np.linalg.norm(np.ptp(truth.vertices, axis=0)))] = 0.0
    angle[cos > 1.0 - ROUNDING] = 0.0
    return points, dist, angle


def worst_junction(pred_mesh: trimesh.Trimesh, gt_mesh: trimesh.Trimesh,
                   gcs: Sequence[GeneralizedCylinder], radius: float, n_samples: int = 30_000,
                   band: float = 0.1, seed: int = 0) -> tuple[np.ndarray, float] | None:
    """(centre (3,), mean distance error there): the junction sample whose ball of `radius`
    on the fitted surface has the largest mean distance to the truth, where a seam would be
    most visible (close-ups: bench/fit.py); None without junction samples."""
    points, dist, _ = surface_errors(pred_mesh, gt_mesh, n_samples, seed)
    j = np.flatnonzero(junction_mask(points, gcs, band))
    if len(j) == 0:
        return None
    tree = cKDTree(points)
    near = cKDTree(points[j]).sparse_distance_matrix(tree, float(radius), output_type="coo_matrix")
    total = np.bincount(near.row, weights=dist[near.col], minlength=len(j))
    local = total / np.maximum(np.bincount(near.row, minlength=len(j)), 1)
    best = int(np.argmax(local))
    return points[j[best]], float(local[best])


def junction_metrics(pred_mesh: trimesh.Trimesh, gt_mesh: trimesh.Trimesh,
                     gcs: Sequence[GeneralizedCylinder], n_samples: int = 30_000,
                     band: float = 0.1, join: float = 0.01, sliver: float = 0.008,
                     seed: int = 0) -> dict:
    """The junction measure of pred_mesh against gt_mesh with the shape's GCs (conventions in
    the module docstring; defaults are conf/metrics/default.yaml's `junctions`).

    Keys: junction_ratio_dist, junction_ratio_normal, junction_ratio_dist_local,
    junction_ratio_normal_local (against the parts that meet), junction_dist, elsewhere_dist (mean
    distances), junction_normal_deg, elsewhere_normal_deg (mean angles), junction_share (share
    of the samples that are junction samples), extra_pieces, pieces, gt_pieces, sliver_breaks
    (fitted pieces not counted extra: cut off where the truth is finer than the grid). A mean over
    no sample, and a ratio with one, is None (JSON null); an empty prediction has only None
    figures and no pieces; an empty truth raises ValueError.
    """
    if is_empty(gt_mesh):
        raise ValueError("ground-truth mesh is empty (no faces or zero area)")
    if is_empty(pred_mesh):
        return {**dict.fromkeys(FIGURES), "extra_pieces": 0, "pieces": 0,
                "gt_pieces": solid_pieces(gt_mesh, join, seed)[1], "sliver_breaks": 0}
    if band < 0:
        raise ValueError(f"band must be >= 0 (a relative radius), got {band}")
    points, dist, angle = surface_errors(pred_mesh, gt_mesh, n_samples, seed)
    rho = relative_radius(points, gcs, band)
    j = (rho <= 1.0 + band).sum(0) >= 2

    def mean(x, m):
        return float(x[m].mean()) if m.any() else None

    out = {"junction_dist": mean(dist, j), "elsewhere_dist": mean(dist, ~j),
           "junction_normal_deg": mean(angle, j), "elsewhere_normal_deg": mean(angle, ~j),
           "junction_share": float(j.mean())}
    out["junction_ratio_dist"] = _ratio(out["junction_dist"], out["elsewhere_dist"])
    out["junction_ratio_normal"] = _ratio(out["junction_normal_deg"], out["elsewhere_normal_deg"])
    out["junction_ratio_dist_local"] = local_ratio(dist, rho, j)
    out["junction_ratio_normal_local"] = local_ratio(angle, rho, j)
    out.update(extra_pieces(pred_mesh, gt_mesh, join, sliver, seed))
    return out
