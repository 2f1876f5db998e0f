"""A closed proxy of any triangle mesh: the input for curve skeletons (docs/autogc.md).

A curve skeleton needs a closed, manifold, single-component surface. Real meshes are open
(pyvista's airplane), made of intersecting pieces (the ant) or both. The proxy is the level set
``field = delta`` of a signed distance on a voxel grid: the unsigned distance to the mesh, negative
where the generalized winding number (libigl) says "inside". Offsetting by ``delta``
closes open sheets into thin slabs and keeps parts thinner than a voxel (1.25 voxels, so a
flat mesh lying on a grid plane does not put the level set exactly on grid nodes). Marching cubes
(scikit-image) gives a closed surface; each connected component is skeletonised on its own.

The winding number needs outward faces. Game meshes often wind them the other way (0 A.D.'s
are clockwise: w = -1 inside), and a model's pieces need not agree; read as they come, such a
mesh is empty inside and its proxy a hollow slab around the surface (two nested shells whose
skeleton is no curve skeleton). So each connected piece (vertices merged by position: UV seams
split a surface into patches) is turned outward first, by the sign of its enclosed volume
(``outward_faces``). A piece that encloses no volume (a flat card: a game model's fringe,
tassel or decal, often a single quad) has no outside: the sign of its volume is rounding
noise that the file's winding decided (read reversed, such a piece turned the other way, its
surface samples and winding with it, and the proxy's surface moved near it), so it takes one
orientation fixed by its vertex indices. The proxy is then the same whichever way the input's
faces are wound.

Cost is kept near the surface: the exact distance (libigl) is computed in a band of a few voxels
around dense surface samples; the winding number is evaluated in that band and at a few voxels
of each connected region outside it (a region is all inside or all outside), not on the grid.
"""
from __future__ import annotations

from dataclasses import dataclass

import igl
import numpy as np
import trimesh
from scipy import ndimage

from ngc_gen.extract.marching import marching_cubes_grid

from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.sampling import sample_surface

BAND = 3.0  # voxels of exact distance around the surface
MERGE = 1e-6  # vertices closer than this x the bounding box are one (``outward_faces``)
#: a piece whose |enclosed volume| is below this x its area^1.5 encloses nothing (a flat card;
#: a closed sphere has 0.094, a cube 0.068)
FLAT = 1e-6


@dataclass
class Proxy:
    """The voxel field and the closed components of its zero level set.

    inside (X, Y, Z) bool: voxels inside the offset surface; origin (3,): world position of voxel
    (0, 0, 0); h: voxel size; components: closed meshes, largest first."""

    inside: np.ndarray
    origin: np.ndarray
    h: float
    components: list[trimesh.Trimesh]

    def voxel_centers(self, ijk: np.ndarray) -> np.ndarray:
        """(N, 3) int voxel indices -> (N, 3) world points."""
        return self.origin + np.asarray(ijk, dtype=np.float64) * self.h


def _pieces(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(piece (F,) of each face, signed volume (P,) about each piece's own centre, area (P,)):
    pieces connect through vertices at the same position (within MERGE x the size)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    size = max(float(np.ptp(V, axis=0).max()), 1e-30)
    _, same = np.unique(np.rint(V / (MERGE * size)).astype(np.int64), axis=0, return_inverse=True)
    G = same.reshape(-1)[F]                                        # (F, 3) merged vertex ids
    n = int(G.max()) + 1
    rows = np.repeat(np.arange(len(F)), 3)
    A = coo_matrix((np.ones(3 * len(F)), (rows, G.ravel())), shape=(len(F), n)).tocsr()
    _, piece = connected_components(A @ A.T, directed=False)      # faces sharing a vertex
    T = V[F]
    centre = np.zeros((piece.max() + 1, 3))
    np.add.at(centre, piece, T.mean(1))
    centre /= np.bincount(piece)[:, None]
    T = T - centre[piece][:, None, :]
    cross = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    vol = np.bincount(piece, weights=np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])))
    area = np.bincount(piece, weights=np.linalg.norm(cross, axis=1) / 2.0)
    return piece, vol, area


def _ascending(F: np.ndarray) -> np.ndarray:
    """(F,) bool: the face's corners, read from its smallest vertex index, ascend (a fixed
    orientation for a piece that has no outside)."""
    lo = F.argmin(1)
    nxt = F[np.arange(len(F)), (lo + 1) % 3]
    prv = F[np.arange(len(F)), (lo + 2) % 3]
    return nxt < prv


def outward_faces(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """faces (F, 3) with every connected piece whose signed volume (about its own centre) is
    negative turned over (its faces wound inward); pieces connect through vertices at the same
    position (within MERGE x the size). A piece enclosing no volume (|volume| < FLAT x
    area^1.5) is turned so that its first face's corners ascend (`_ascending`): the same
    whichever way the input is wound."""
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    if len(F) == 0:
        return F
    piece, vol, area = _pieces(V, F)
    flat = np.abs(vol) < FLAT * area ** 1.5
    first = np.full(len(vol), len(F))
    np.minimum.at(first, piece, np.arange(len(F)))
    flip = np.where(flat, ~_ascending(F[first]), vol < 0)[piece]
    return np.where(flip[:, None], F[:, ::-1], F)


def closed_proxy(vertices: np.ndarray, faces: np.ndarray, resolution: int = 96,
                 offset: float = 1.25, seed: int = 0) -> Proxy:
    """Closed proxy of the mesh (vertices (V, 3), faces (F, 3)).

    resolution: voxels along the longest side of the bounding box; offset: delta in voxels.
    Raises DataError if the mesh has no area or the proxy is empty."""
    V = np.ascontiguousarray(vertices, dtype=np.float64)
    F = np.ascontiguousarray(outward_faces(V, faces), dtype=np.int64)
    lo, hi = V.min(axis=0), V.max(axis=0)
    size = float((hi - lo).max())
    if not size > 0:
        raise DataError("all vertices coincide, the mesh has no extent", field="mesh",
                        fix="give a mesh with a non-degenerate bounding box")
    h = size / resolution
    pad = (BAND + offset + 2.0) * h
    origin = lo - pad
    shape = tuple(int(n) for n in np.ceil((hi + pad - origin) / h).astype(int) + 1)

    # surface voxels from dense samples (about 4 per voxel face), then a band around them
    area = float(np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]),
                                axis=1).sum() / 2.0)
    n = int(min(4.0 * area / h ** 2, 2_000_000)) + len(V)
    P, _ = sample_surface(V, F, n, np.random.default_rng(seed))
    P = np.concatenate([V, P])
    ijk = np.clip(np.rint((P - origin) / h).astype(np.int64), 0, np.array(shape) - 1)
    surf = np.zeros(shape, dtype=bool)
    surf[tuple(ijk.T)] = True
    band = ndimage.distance_transform_edt(~surf) <= BAND
    band_idx = np.argwhere(band)
    Q = origin + band_idx * h
    d2, _, _ = igl.point_mesh_squared_distance(Q, V, F)
    udf = np.full(shape, (BAND + 1.0) * h)
    udf[band] = np.sqrt(d2)

    # inside: winding number in the band; outside the band one vote per connected region
    inside = np.zeros(shape, dtype=bool)
    inside[band] = igl.fast_winding_number(V, F, Q) > 0.5
    labels, n_regions = ndimage.label(~band)
    if n_regions:
        flat = labels.ravel()
        order = np.argsort(flat, kind="stable")
        starts = np.searchsorted(flat[order], np.arange(1, n_regions + 1))
        counts = np.bincount(flat, minlength=n_regions + 1)[1:]
        take = np.minimum(counts, 8)
        picks = np.concatenate([order[s + np.linspace(0, c - 1, k).astype(np.int64)]
                                for s, c, k in zip(starts, counts, take)])
        owner = flat[picks]
        votes = igl.fast_winding_number(V, F, origin + np.stack(np.unravel_index(picks, shape), 1) * h)
        region_in = (np.bincount(owner, weights=(votes > 0.5).astype(float), minlength=n_regions + 1)
                     > 0.5 * np.bincount(owner, minlength=n_regions + 1))
        region_in[0] = False
        inside |= region_in[labels]
    field = np.where(inside, -udf, udf) - offset * h
    if not (field < 0).any():
        raise DataError("the mesh encloses no volume even after offsetting", field="mesh",
                        fix="give a surface mesh with faces of non-zero area")
    proxy = marching_cubes_grid(field, origin, h, float32_spacing=True)
    # marching cubes leaves a few degenerate slivers; a real component is closed with volume
    comps = [c for c in proxy.split(only_watertight=False)
             if c.is_watertight and abs(c.volume) > (2.0 * h) ** 3]
    if not comps:
        raise DataError("the closed proxy of the mesh is empty", field="mesh",
                        fix="raise annotate.resolution so the mesh's parts span a few voxels")
    comps = sorted(comps, key=lambda c: (-len(c.faces), tuple(np.round(c.bounds[0], 6))))
    return Proxy(inside=field < 0, origin=origin, h=h, components=list(comps))


def decimated(mesh: trimesh.Trimesh, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a closed manifold mesh reduced to at most ``max_faces`` faces by
    libigl's edge collapse (which keeps it closed and manifold)."""
    if len(mesh.faces) <= max_faces:
        return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    V, F, _, _ = igl.decimate(np.asfortranarray(mesh.vertices, dtype=np.float64),
                              np.asfortranarray(mesh.faces, dtype=np.int32), int(max_faces))
    return np.ascontiguousarray(V), np.ascontiguousarray(F, dtype=np.int64)
