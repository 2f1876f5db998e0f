"""Automatic GCs, one per limb or part, from any mesh (docs/autogc.md).

closed proxy (``proxy``) -> curve skeleton (``skeleton``) -> branch graph (``branches``) -> one
cubic Bezier GC per branch (``branch_gc``) -> names (``gc_names``) -> local growth until the GCs
cover the surface (``coverage``). Deterministic: every random draw uses ``settings.seed``.
"""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from ngc_gen.geometry import GeneralizedCylinder

from ngc_gen.data.autogc.branch_gc import branch_gc, resample, split_bulb, split_curved
from ngc_gen.data.autogc.branches import Branch, branch_graph, junction_key, pass_through
from ngc_gen.data.autogc.coverage import grow_to_cover
from ngc_gen.data.autogc.names import gc_names
from ngc_gen.data.autogc.orient import detect_orientation, parse_axis
from ngc_gen.data.autogc.protrusions import THINNER as protrusion_thinner
from ngc_gen.data.autogc.protrusions import half_thickness, protrusion_branches
from ngc_gen.data.mesh.proxy import closed_proxy
from ngc_gen.data.mesh.sampling import sample_surface
from ngc_gen.data.errors import DataError
from ngc_gen.data.autogc.skeleton import BACKENDS, local_thickness, proxy_skeleton

CURVE_TOLERANCE = 0.05  # split a branch when its cubic strays more than this x its length


def _exit_index(radius: np.ndarray) -> int:
    """Index along a branch (from its junction end) where it leaves the body it grows from:
    the first node whose thickness is within 25% of the branch's own (the median over its
    outer half)."""
    own = float(np.median(radius[len(radius) // 2:]))
    return int(np.argmax(radius <= 1.25 * own))


def _rooted(branches: list[Branch], through: dict | None = None
            ) -> tuple[list[Branch], np.ndarray, np.ndarray, list[Branch]]:
    """Branches with their roots trimmed, the skeleton samples (M, 3) with their owner (M,), and
    the untrimmed resampled branches (whose points, concatenated, are those samples).

    At a junction, every branch but the thickest starts inside the thickest one's body; the
    samples up to where it leaves that body belong to the thickest branch (a torso's surface
    around a tail root is the torso's), and its GC starts halfway between the junction and
    that exit, so it overlaps its parent a little instead of running through it. `through`:
    junction key -> a branch that passes through that junction (`pass_through`), a rival there."""
    ends: dict = {}
    for i, b in enumerate(branches):
        for side in (0, -1):
            if b.junction[side]:
                ends.setdefault(junction_key(b.points[side]), []).append((float(b.radius.mean()), -i))
    for key, i in (through or {}).items():
        ends.setdefault(key, []).append((float(branches[i].radius.mean()), -i))
    samples, owner, out, full = [], [], [], []
    for i, b in enumerate(branches):
        P, R = b.points, b.radius
        if len(P) > 1:
            n = max(8, int(np.ceil(b.length / max(float(R.min()), 1e-3) * 4)))
            P, s_nodes = resample(b.points, n)
            R = np.interp(np.linspace(0.0, 1.0, n), s_nodes, b.radius)
        lab = np.full(len(P), i)
        lo, hi = 0, len(P)
        for side in (0, -1):
            if not b.junction[side] or len(P) < 4:
                continue
            rivals = ends[junction_key(b.points[side])]
            thickest = -max(rivals)[1]
            if thickest == i:
                continue
            k = _exit_index(R if side == 0 else R[::-1])
            if side == 0:
                lab[:k] = thickest
                lo = max(lo, k // 2)
            else:
                lab[len(P) - k:] = thickest
                hi = min(hi, len(P) - k // 2)
        if hi - lo < 2:
            lo, hi = 0, len(P)
        samples.append(P)
        owner.append(lab)
        out.append(Branch(P[lo:hi], R[lo:hi], b.junction, b.component))
        full.append(Branch(P, R, b.junction, b.component))
    return out, np.concatenate(samples), np.concatenate(owner), full


def _tangent(P: np.ndarray) -> np.ndarray:
    """(P, 3) unit tangent of a polyline (P, 3) at each point."""
    t = np.gradient(P, axis=0) if len(P) > 1 else np.zeros_like(P)
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)


def _split_owner(pieces: list[Branch], piece_of: list[np.ndarray], owner: np.ndarray,
                 surface: np.ndarray) -> np.ndarray:
    """Owner indices from branches to pieces: a split branch's points go to its nearest piece."""
    out = np.empty_like(owner)
    for i, idx in enumerate(piece_of):
        mine = owner == i
        if len(idx) == 1:
            out[mine] = idx[0]
            continue
        pts = np.concatenate([pieces[j].points for j in idx])
        lab = np.concatenate([np.full(len(pieces[j].points), j) for j in idx])
        out[mine] = lab[cKDTree(pts).query(surface[mine], k=1)[1]]
    return out


def skeleton_gcs(mesh: trimesh.Trimesh, *, max_gcs: int, min_branch_length: float,
                 margin: float, resolution: int, skeleton: str, n_keys: int, samples: int,
                 seed: int, protrusions: bool, bulb_ratio: float, up, front
                 ) -> tuple[list[GeneralizedCylinder], dict]:
    """GCs for a (normalised) mesh and what was found on the way: {backend, n_branches,
    n_components, n_protrusions, orientation}; names by the given or detected up and front
    (``orient``). Arguments: the fields of `AutoGCSettings` but `method` (`auto_gcs` passes
    them; their values live in conf/annotate/default.yaml)."""
    if skeleton not in BACKENDS:
        raise DataError(f"unknown skeleton backend {skeleton!r}", field="annotate.skeleton",
                        fix=f"use one of {', '.join(BACKENDS)}")
    V, F = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    rng = np.random.default_rng(seed)
    pts, nrm = sample_surface(V, F, samples, rng)
    surface = np.concatenate([V, pts])
    proxy = closed_proxy(V, F, resolution=resolution, seed=seed)
    sk = proxy_skeleton(proxy, backend=skeleton)
    radius = np.maximum(local_thickness(sk.nodes, surface), proxy.h)
    branches = branch_graph(sk.nodes, sk.edges, radius, min_branch_length, max_gcs)
    branches, through = pass_through(branches)
    rooted, nodes, node_owner, branches_full = _rooted(branches, through)
    n_skeleton = len(rooted)
    node_tree = cKDTree(nodes)
    d_near, near = node_tree.query(surface, k=1)
    owner = node_owner[near]
    # cross-section radius per node: mean distance of the surface samples nearest to it
    count = np.bincount(near, minlength=len(nodes))
    section = np.bincount(near, weights=d_near, minlength=len(nodes)) / np.maximum(count, 1)
    section[count == 0] = np.nan
    if protrusions and len(rooted) < max_gcs:  # thin parts the skeleton merged into a body
        node_r = np.maximum(local_thickness(nodes, surface), proxy.h)
        comp = np.array([b.component for b in branches])[node_owner]
        body = np.array([np.median(node_r[node_owner == i]) for i in range(len(rooted))])
        normals = np.concatenate([np.asarray(mesh.vertex_normals, dtype=np.float64), nrm])
        width = half_thickness(surface, normals, proxy.inside, proxy.origin, proxy.h)
        extra = protrusion_branches(surface, nodes, node_r, comp, link=2.0 * proxy.h, width=width,
                                    tangent=np.concatenate([_tangent(b.points) for b in branches_full]),
                                    body=body[node_owner], min_length=min_branch_length,
                                    max_new=max_gcs - len(rooted))
        if extra:
            new_nodes = np.concatenate([b.points for b in extra])
            new_owner = np.concatenate([np.full(len(b.points), len(rooted) + k) for k, b in enumerate(extra)])
            rooted += extra
            d_new, k_new = cKDTree(new_nodes).query(surface, k=1)
            d_old = cKDTree(nodes).query(surface, k=1)[0]
            # a protrusion holds the samples nearer its axis than the body's and thin like it
            # (its root's surface on the body, as thick as the body, stays the body's)
            mine = (d_new < d_old) & (width <= protrusion_thinner * body[owner])
            owner = np.where(mine, new_owner[k_new], owner)
    pieces, piece_of = [], []  # a branch too curved for one cubic is split, its points too
    for i, b in enumerate(rooted):
        parts = [b]
        if i < n_skeleton and len(rooted) + 1 <= max_gcs:  # a head on its neck, then curvature
            sec = section[node_tree.query(b.points, k=1)[1]]
            parts = [c for p in split_bulb(b, bulb_ratio, min_branch_length, sec)
                     for c in split_curved(p, CURVE_TOLERANCE)]
        piece_of.append(np.arange(len(pieces), len(pieces) + len(parts)))
        pieces += parts
    owner = _split_owner(pieces, piece_of, owner, surface)
    gcs = [branch_gc(b, surface[owner == i], f"gc_{i}", n_keys=n_keys, margin=margin)
           for i, b in enumerate(pieces)]
    gcs = grow_to_cover(gcs, surface, owner=owner, groups=np.array([b.component for b in pieces]))
    curves = [np.asarray(g.to_world(np.stack([np.linspace(-1, 1, 17), np.zeros(17), np.zeros(17)], 1)))
              for g in gcs]
    volumes = [b.length * float(np.mean(b.radius)) ** 2 for b in pieces]  # from the skeleton
    comps = [b.component for b in pieces]
    main = [i for i in range(len(pieces)) if comps[i] == max(set(comps), key=lambda c: (
        sum(v for v, k in zip(volumes, comps) if k == c), -c))]
    trunk = max(main, key=lambda i: volumes[i])
    orientation = detect_orientation([curves[i] for i in main], [volumes[i] for i in main],
                                     main.index(trunk), parse_axis(up, "annotate.up"),
                                     parse_axis(front, "annotate.front"), surface)
    names = gc_names(curves, volumes, comps, orientation.matrix)
    named = sorted((GeneralizedCylinder.from_dict({**g.to_dict(), "name": nm}) for g, nm in zip(gcs, names)),
                   key=lambda g: (g.name != "trunk", g.name))
    info = {"backend": sk.backend, "n_branches": len(branches), "n_components": len(proxy.components),
            "n_protrusions": len(rooted) - len(branches), "orientation": orientation}
    return named, info
