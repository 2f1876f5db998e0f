"""Corrective shapes at a fold: where skinning folds a joint's inside into its neighbour, the
skinned normals of adjacent vertices cross, their rays reach different sheets of the posed
surface and the faces between them span the crease off the surface (fins). With the shipped
settings the corrected mesh lies on the surface, faces included, not only its vertices; where
nothing folds, `unfold` moves nothing."""
from __future__ import annotations

import numpy as np
import trimesh

from ngc_gen.export import ExportSettings
from ngc_gen.export.correctives import corrective_offsets

HALF = np.radians(30)  # the valley's sides rise at this slope


def valley(p):
    """A concave crease along y: the union of the half-spaces below z = x tan a and z = -x tan a
    (a leg meeting the torso), exact outside."""
    p = np.asarray(p, np.float64)
    a = np.array([-np.sin(HALF), 0.0, np.cos(HALF)])
    b = np.array([np.sin(HALF), 0.0, np.cos(HALF)])
    return np.minimum(p @ a, p @ b)


def grid(spacing=0.04, n=10, depth=-0.1):
    """A flat n x n grid of triangles inside the solid, below the crease (no vertex on x = 0)."""
    g = (np.arange(n) - n / 2 + 0.5) * spacing
    X, Y = np.meshgrid(g, g, indexing="ij")
    V = np.stack([X.ravel(), Y.ravel(), np.full(X.size, depth)], 1)
    idx = np.arange(n * n).reshape(n, n)
    q = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
    return V, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def correct(V, N, F, rounds):
    s = ExportSettings.from_yaml()
    fold = {"rounds": s.fold_rounds if rounds is None else rounds, "stretch": s.fold_stretch,
            "off": s.fold_off}
    J = np.zeros((len(V), 4), np.int64)
    W = np.zeros((len(V), 4))
    W[:, 0] = 1.0  # one joint at identity: the skinned mesh is the rest mesh
    _, y = corrective_offsets(V, N, F, J, W, np.eye(4)[None], valley, s.newton_steps,
                              s.fd_step, s.max_step, s.tolerance, fold)
    return y


def off_surface(y, F):
    """Mean squared field value over points spread on the mesh's faces (the exported surface's
    half of a squared Chamfer against the valley)."""
    p, _ = trimesh.sample.sample_surface(trimesh.Trimesh(y, F, process=False), 20_000, seed=0)
    return float((valley(p) ** 2).mean())


def test_crossed_normals_leave_no_fins():
    V, F = grid()
    b = np.radians(45)  # the fold: each side's normals lean over to the other side
    N = np.stack([-np.sign(V[:, 0]) * np.sin(b), np.zeros(len(V)), np.full(len(V), np.cos(b))], 1)
    rays_only = correct(V, N, F, rounds=0)
    y = correct(V, N, F, rounds=None)  # the shipped settings
    assert np.abs(valley(rays_only)).max() < 1e-3  # every vertex is on the surface either way
    assert off_surface(rays_only, F) > 5e-4  # but faces span the crease: the case is real
    assert off_surface(y, F) < off_surface(rays_only, F) / 10
    assert np.abs(valley(y)).max() < 1e-3


def test_no_fold_moves_nothing():
    V, F = grid()
    N = np.tile([0.0, 0.0, 1.0], (len(V), 1))  # straight up onto the valley: nothing crosses
    y = correct(V, N, F, rounds=None)
    assert np.array_equal(y, correct(V, N, F, rounds=0))
    assert off_surface(y, F) < 1e-4
