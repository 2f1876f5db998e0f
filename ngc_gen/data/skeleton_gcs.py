"""Automatic GCs, one per limb or part, from any mesh (DESIGN.md section 8).

closed proxy (``proxy``) -> curve skeleton (``skeleton``) -> branch graph (``branches``) -> one
cubic Bezier GC per branch (``branch_gc``) -> names (``gc_names``) -> local growth until the GCs
cover the surface (``coverage``). Deterministic: every random draw uses ``settings.seed``.
"""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ngc_gen.geometry import GeneralizedCylinder

from .branch_gc import branch_gc, resample, split_curved
from .branches import Branch, branch_graph
from .coverage import grow_to_cover
from .gc_names import gc_names
from .proxy import closed_proxy
from .sampling import sample_surface
from .skeleton import local_thickness, proxy_skeleton

CURVE_TOLERANCE = 0.05  # split a branch when its cubic strays more than this x its length


def _owners(branches: list[Branch], points: np.ndarray) -> np.ndarray:
    """(N,) index of the branch each surface point belongs to: the branch with the nearest
    polyline point, where a branch that is not the thickest at one of its junctions gives up
    its nodes inside that junction's ball (a torso's surface near a leg root is the torso's)."""
    samples, owner = [], []
    ends = {}
    for i, b in enumerate(branches):
        for side in (0, -1):
            if b.junction[side]:
                ends.setdefault(tuple(np.round(b.points[side], 9)), []).append((float(b.radius.mean()), i))
    for i, b in enumerate(branches):
        P = resample(b.points, max(8, int(np.ceil(b.length / max(b.radius.min(), 1e-3) * 4))))[0] \
            if len(b.points) > 1 else b.points
        keep = np.ones(len(P), dtype=bool)
        for side in (0, -1):
            if not b.junction[side]:
                continue
            rivals = ends[tuple(np.round(b.points[side], 9))]
            if max(rivals)[1] != i:
                keep &= np.linalg.norm(P - b.points[side], axis=1) > b.radius[side]
        if not keep.any():
            keep[len(P) // 2] = True
        samples.append(P[keep])
        owner.append(np.full(int(keep.sum()), i))
    tree = cKDTree(np.concatenate(samples))
    return np.concatenate(owner)[tree.query(points, k=1)[1]]


def skeleton_gcs(mesh: trimesh.Trimesh, max_gcs: int = 24, min_branch_length: float = 2.0,
                 margin: float = 0.05, resolution: int = 96, skeleton: str = "auto",
                 n_keys: int = 5, samples: int = 20000, seed: int = 0
                 ) -> tuple[list[GeneralizedCylinder], dict]:
    """GCs for a (normalised) mesh and what was found on the way: {backend, n_branches,
    n_components}. Arguments as in conf/annotate/default.yaml."""
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    rng = np.random.default_rng(seed)
    surface = np.concatenate([V, sample_surface(V, F, samples, rng)[0]])
    proxy = closed_proxy(V, F, resolution=resolution, seed=seed)
    sk = proxy_skeleton(proxy, backend=skeleton)
    radius = np.maximum(local_thickness(sk.nodes, surface), proxy.h)
    branches = branch_graph(sk.nodes, sk.edges, radius, min_branch_length, max_gcs)
    pieces = [p for b in branches for p in split_curved(b, CURVE_TOLERANCE)]
    if len(pieces) > max_gcs:  # splitting curved branches must not exceed the budget either
        pieces = branches
    owner = _owners(pieces, surface)
    gcs = [branch_gc(b, surface[owner == i], f"gc_{i}", n_keys=n_keys, margin=margin)
           for i, b in enumerate(pieces)]
    gcs = grow_to_cover(gcs, surface)
    curves = [np.asarray(g.to_world(np.stack([np.linspace(-1, 1, 17), np.zeros(17), np.zeros(17)], 1)))
              for g in gcs]
    volumes = [float(np.prod(np.mean([k.radii for k in g.keys], axis=0))) * g.length for g in gcs]
    names = gc_names(curves, volumes, [b.component for b in pieces])
    named = sorted((GeneralizedCylinder.from_dict({**g.to_dict(), "name": nm}) for g, nm in zip(gcs, names)),
                   key=lambda g: (g.name != "trunk", g.name))
    info = {"backend": sk.backend, "n_branches": len(branches), "n_components": len(proxy.components)}
    return named, info
