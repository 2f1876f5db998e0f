"""Curve skeletons of closed proxies (docs/autogc.md), as a graph of nodes and edges.

Two backends:
- ``cgal``: CGAL's mean-curvature-flow skeleton (Tagliasacchi et al. 2012) through the
  ``compas-cgal`` wheel (LGPLv3, optional): one call per closed component, after libigl's edge
  collapse brings it to a few thousand faces (the flow costs about 0.2-0.6 s there).
- ``voxel``: scikit-image's 3-D thinning (``skeletonize``) of the proxy's inside voxels, the
  skeleton voxels joined to their 26-neighbours.
``auto`` takes ``cgal`` when the wheel is installed and falls back to ``voxel`` for a component
where the flow fails (it raises on meshes it cannot contract).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from skimage.morphology import skeletonize

from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.proxy import Proxy, decimated

log = logging.getLogger(__name__)

BACKENDS = ("auto", "cgal", "voxel")


@dataclass
class Skeleton:
    """nodes (N, 3) float64, edges (E, 2) int64 (i < j, unique), backend: what made it."""

    nodes: np.ndarray
    edges: np.ndarray
    backend: str


def cgal_available() -> bool:
    try:
        import compas_cgal.skeletonization  # noqa: F401
    except ImportError:
        return False
    return True


def _graph_from_segments(a: np.ndarray, b: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Segments (S, 3) a -> b to (nodes, edges): endpoints closer than tol are one node."""
    pts = np.concatenate([a, b])
    key = np.rint(pts / tol).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    nodes = pts[first]
    e = np.sort(np.stack([inv[: len(a)], inv[len(a):]], axis=1), axis=1)
    e = np.unique(e[e[:, 0] != e[:, 1]], axis=0)
    return nodes, e


def mcf_skeleton(vertices: np.ndarray, faces: np.ndarray, max_faces: int = 10000) -> Skeleton:
    """CGAL mean-curvature-flow skeleton of one closed manifold mesh (raises ImportError without
    compas-cgal, RuntimeError/ValueError when CGAL cannot contract the mesh)."""
    import trimesh
    from compas_cgal.skeletonization import mesh_skeleton

    V, F = decimated(trimesh.Trimesh(vertices, faces, process=False), max_faces)
    segments = np.asarray(mesh_skeleton((V, F)), dtype=np.float64)  # (S, 2, 3)
    if segments.ndim != 3 or len(segments) == 0:
        raise RuntimeError("CGAL returned an empty skeleton")
    size = float(np.ptp(V, axis=0).max())
    nodes, edges = _graph_from_segments(segments[:, 0], segments[:, 1], 1e-9 * size)
    return Skeleton(nodes, edges, "cgal")


# the 13 forward neighbour offsets of a 26-neighbourhood (the other 13 are their negatives)
_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                     if (i, j, k) > (0, 0, 0)], dtype=np.int64)


def voxel_skeleton(inside: np.ndarray, origin: np.ndarray, h: float) -> Skeleton:
    """Thinning of a boolean voxel volume; skeleton voxels become nodes at their centres, joined
    to their 26-neighbours (small cycles at junctions are left for the branch graph to cut)."""
    skel = skeletonize(np.pad(inside, 1)).astype(bool)[1:-1, 1:-1, 1:-1]
    ijk = np.argwhere(skel)
    if len(ijk) == 0:
        raise DataError("voxel thinning left no skeleton", field="mesh",
                        fix="raise annotate.resolution so thin parts span a few voxels")
    index = -np.ones(np.array(inside.shape) + 2, dtype=np.int64)  # padded so +-1 stays in range
    index[tuple((ijk + 1).T)] = np.arange(len(ijk))
    nb = index[tuple((ijk[:, None, :] + 1 + _OFFSETS[None]).transpose(2, 0, 1))]  # (N, 13)
    src = np.repeat(np.arange(len(ijk)), len(_OFFSETS)).reshape(nb.shape)
    ok = nb >= 0
    edges = np.sort(np.stack([src[ok], nb[ok]], axis=1), axis=1)
    return Skeleton(origin + ijk * h, np.unique(edges, axis=0), "voxel")


def _voxels_of(proxy: Proxy, mesh) -> np.ndarray:
    """The proxy's inside voxels enclosed by one of its component meshes (its bounding box, then
    the connected inside region that has most voxels there)."""
    from scipy import ndimage

    labels, _ = ndimage.label(proxy.inside)
    lo = np.clip(np.floor((mesh.bounds[0] - proxy.origin) / proxy.h).astype(int), 0, None)
    hi = np.ceil((mesh.bounds[1] - proxy.origin) / proxy.h).astype(int) + 1
    box = labels[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
    counts = np.bincount(box.ravel(), minlength=labels.max() + 1)
    counts[0] = 0
    return labels == int(np.argmax(counts))


def proxy_skeleton(proxy: Proxy, backend: str = "auto", max_faces: int = 10000) -> Skeleton:
    """One skeleton graph over all components of the proxy (disconnected per component)."""
    if backend not in BACKENDS:
        raise DataError(f"unknown skeleton backend {backend!r}", field="annotate.skeleton",
                        fix=f"use one of {', '.join(BACKENDS)}")
    use_cgal = backend == "cgal" or (backend == "auto" and cgal_available())
    if backend == "cgal" and not cgal_available():
        raise DataError("the cgal skeleton needs the compas-cgal package", field="annotate.skeleton",
                        fix="pip install compas-cgal, or set annotate.skeleton=voxel")
    parts, used = [], set()
    for comp in proxy.components:
        sk = None
        if use_cgal:
            try:
                sk = mcf_skeleton(comp.vertices, comp.faces, max_faces)
            except (RuntimeError, ValueError) as e:
                if backend == "cgal":
                    raise DataError(f"CGAL could not skeletonise a component ({e})", field="mesh",
                                    fix="set annotate.skeleton=voxel (voxel thinning)") from e
                log.info("mean-curvature-flow skeleton failed (%s); voxel thinning instead", e)
        if sk is None:
            sk = voxel_skeleton(_voxels_of(proxy, comp), proxy.origin, proxy.h)
        parts.append(sk)
        used.add(sk.backend)
    offsets = np.cumsum([0] + [len(p.nodes) for p in parts])
    return Skeleton(np.concatenate([p.nodes for p in parts]),
                    np.concatenate([p.edges + o for p, o in zip(parts, offsets)]),
                    "+".join(sorted(used)))


def local_thickness(nodes: np.ndarray, surface: np.ndarray) -> np.ndarray:
    """(N,) distance from each skeleton node to the nearest surface sample (surface (S, 3))."""
    return cKDTree(surface).query(nodes, k=1)[0]
