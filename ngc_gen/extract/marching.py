"""Marching cubes (scikit-image, Lewiner) over chosen cells of the grid, in bricks.

Only cells whose 8 corner values change sign produce triangles. They are grouped into bricks of
`brick` cells per axis; each brick is a small dense array (values where known, a positive filler
elsewhere) with a mask that lets scikit-image visit only the listed cells (it reads the mask at a
cell's far corner, (x+1, y+1, z+1)), so memory and time follow the surface, not the volume.
Bricks sit on a fixed lattice, so a vertex on a face shared by two bricks has the same local
coordinate along that face in both and comes out bit-identical: duplicates are merged exactly.
The dense grid (`marching_cubes_mesh`) goes through the same code, so a sparse and a dense
extraction with equal values at the sign-change cells give the same mesh, bit for bit.

Specks are left out: a connected component less than 2 cells wide along every axis, typically
the 8 triangles around one grid sample that marching cubes separates from its neighbours (a
floater, or a pinhole bubble). The grid says nothing about such a piece's shape; specks appear
where a tip or a thin part narrows below the grid spacing, for the exact distance field as much
as for a fit (`speck_faces`).
"""
from __future__ import annotations

import numpy as np
import trimesh
from numba import njit
from skimage.measure import marching_cubes

from .grid import Grid

# corner offsets of a cell, in the order corners are passed around: (dx, dy, dz), dx slowest
CORNERS = np.array([(dx, dy, dz) for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)],
                   dtype=np.int64)
BRICK = 16           # cells per brick side
BRICKS_PER_BATCH = 256


def empty_mesh() -> trimesh.Trimesh:
    return trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=np.int64),
                           process=False)


def marching_cubes_grid(values: np.ndarray, origin, spacing: float, level: float = 0.0,
                        process: bool = True, float32_spacing: bool = False) -> trimesh.Trimesh:
    """The level-`level` surface of a value grid (negative inside) whose index (i, j, k) lies at
    origin + spacing * (i, j, k): the one place marching cubes runs (scikit-image, Lewiner).

    Faces are oriented with normals toward increasing values (outward for an SDF), so a closed
    surface has positive volume. No crossing of `level` gives an empty mesh, not an error.
    float32_spacing: scale in scikit-image (float32 vertices before the shift), as the procedural
    creatures were built, which keeps the shipped creature set bit-identical; otherwise float64."""
    values = np.asarray(values)
    if not (values.min() < level < values.max()):
        return empty_mesh()
    # 'descent' orients faces with the object (lower values) behind them: outward for an SDF
    verts, faces, _, _ = marching_cubes(
        values, level=level, gradient_direction="descent", allow_degenerate=False,
        spacing=(float(spacing),) * 3 if float32_spacing else (1.0, 1.0, 1.0))
    scale = 1.0 if float32_spacing else float(spacing)
    verts = verts.astype(np.float64) * scale + np.asarray(origin, dtype=np.float64)
    return trimesh.Trimesh(vertices=verts, faces=faces, process=process)


def crossing(values: np.ndarray, level: float = 0.0) -> np.ndarray:
    """values (n, 8) corner values -> (n,) bool: the cell has corners on both sides of level."""
    below = (values < level).sum(1)
    return (below > 0) & (below < 8)


def first_of_equal_rows(a: np.ndarray) -> np.ndarray:
    """(n, 3) float rows -> (n,) index of the first row equal to each (a sort, not a hash)."""
    order = np.lexsort((a[:, 2], a[:, 1], a[:, 0]))
    s = a[order]
    new = np.ones(len(a), dtype=bool)
    new[1:] = np.any(s[1:] != s[:-1], axis=1)
    group = np.cumsum(new) - 1
    first = np.full(group[-1] + 1 if len(a) else 0, len(a), dtype=np.int64)
    np.minimum.at(first, group, order)
    out = np.empty(len(a), dtype=np.int64)
    out[order] = first[group]
    return out


def speck_faces(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """verts (V, 3) in grid-index units, faces (F, 3) -> (F,) bool: the face belongs to a speck,
    a connected component less than 2 cells wide along every axis (its vertices all lie on the
    edges of one grid sample, or of a pinhole between samples). Components by union-find over
    the faces' edges in one compiled pass (a third of the time of scipy's graph components on
    the creature at 256)."""
    out = np.empty(len(faces), dtype=bool)
    if len(faces):
        _speck_kernel(np.ascontiguousarray(verts, dtype=np.float64),
                      np.ascontiguousarray(faces, dtype=np.int64), out)
    return out


@njit(cache=True)
def _root(parent, a):
    while parent[a] != a:
        parent[a] = parent[parent[a]]            # path halving
        a = parent[a]
    return a


@njit(cache=True)
def _speck_kernel(verts, faces, out):
    n = verts.shape[0]
    parent = np.arange(n)
    for f in range(faces.shape[0]):
        for e in range(2):
            a, b = _root(parent, faces[f, e]), _root(parent, faces[f, e + 1])
            if a != b:
                parent[max(a, b)] = min(a, b)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    for f in range(faces.shape[0]):
        for c in range(3):
            v = faces[f, c]
            r = _root(parent, v)
            for a in range(3):
                lo[r, a] = min(lo[r, a], verts[v, a])
                hi[r, a] = max(hi[r, a], verts[v, a])
    for f in range(faces.shape[0]):
        r = _root(parent, faces[f, 0])
        out[f] = (hi[r, 0] - lo[r, 0] < 2.0 and hi[r, 1] - lo[r, 1] < 2.0
                  and hi[r, 2] - lo[r, 2] < 2.0)


def cells_mesh(cells: np.ndarray, values: np.ndarray, grid: Grid, level: float = 0.0,
               brick: int = BRICK, keep_specks: bool = False) -> trimesh.Trimesh:
    """cells (n, 3) int64 index of each cell's first corner (all corners <= R - 1), values
    (n, 8) float32 at its corners (CORNERS order) -> the level surface through those cells in
    world coordinates, faces oriented with normals toward increasing values (outward for an
    SDF). Cells without a crossing are skipped, and so are specks unless `keep_specks` (module
    docstring); no crossing at all gives an empty mesh."""
    keep = crossing(values, level)
    cells, values = cells[keep], values[keep]
    if len(cells) == 0:
        return empty_mesh()
    bidx = cells // brick
    nb_axis = int(bidx.max()) + 1
    bkey = (bidx[:, 0] * nb_axis + bidx[:, 1]) * nb_axis + bidx[:, 2]
    order = np.argsort(bkey, kind="stable")
    cells, values, bidx, bkey = cells[order], values[order], bidx[order], bkey[order]
    start = np.flatnonzero(np.concatenate([[True], bkey[1:] != bkey[:-1]]))
    stop = np.append(start[1:], len(cells))
    bricks = bidx[start]
    verts, faces, edge, n_verts = [], [], [], 0
    filler = np.float32(level + 1.0)   # never read: masked-out cells are not visited
    for b0 in range(0, len(bricks), BRICKS_PER_BATCH):
        b1 = min(b0 + BRICKS_PER_BATCH, len(bricks))
        lo, hi = start[b0], stop[b1 - 1]
        nb = b1 - b0
        vol = np.full((nb, brick + 1, brick + 1, brick + 1), filler, dtype=np.float32)
        mask = np.zeros((nb, brick + 1, brick + 1, brick + 1), dtype=bool)
        which = np.repeat(np.arange(nb), stop[b0:b1] - start[b0:b1])
        local = cells[lo:hi] - bricks[b0:b1][which] * brick
        for c, (dx, dy, dz) in enumerate(CORNERS):
            vol[which, local[:, 0] + dx, local[:, 1] + dy, local[:, 2] + dz] = values[lo:hi, c]
        mask[which, local[:, 0] + 1, local[:, 1] + 1, local[:, 2] + 1] = True
        for j in range(nb):
            try:
                v, f, _, _ = marching_cubes(vol[j], level=level, mask=mask[j],
                                            gradient_direction="descent",
                                            allow_degenerate=False)
            except RuntimeError:   # every triangle of the brick was degenerate
                continue
            if len(f):
                edge.append(np.any((v == 0) | (v == brick), axis=1))
                verts.append(v.astype(np.float64) + bricks[b0 + j] * brick)
                faces.append(f.astype(np.int64) + n_verts)
                n_verts += len(v)
    if not faces:
        return empty_mesh()
    verts, faces, edge = np.concatenate(verts), np.concatenate(faces), np.concatenate(edge)
    # a vertex on a brick face may come from both bricks, bit-identical: keep the first
    rep = np.arange(len(verts))
    on_edge = np.flatnonzero(edge)
    rep[on_edge] = on_edge[first_of_equal_rows(verts[on_edge])]
    faces = rep[faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
                  & (faces[:, 0] != faces[:, 2])]
    if not keep_specks and len(faces):
        faces = faces[~speck_faces(verts, faces)]
        if not len(faces):
            return empty_mesh()
    used = np.zeros(len(verts), dtype=bool)
    used[faces.reshape(-1)] = True
    index = np.cumsum(used) - 1
    world = verts[used] * grid.spacing - grid.bound
    np.clip(world, -grid.bound, grid.bound, out=world)  # rounding only: indices in [0, R-1]
    return trimesh.Trimesh(vertices=world, faces=index[faces], process=False)


def marching_cubes_mesh(values: np.ndarray, grid: Grid, level: float = 0.0,
                        keep_specks: bool = False) -> trimesh.Trimesh:
    """values: (R, R, R) float grid over `grid` (negative inside) -> the level-`level` surface,
    through the same bricked code as the sparse path (specks left out unless `keep_specks`)."""
    values = np.asarray(values, dtype=np.float32)
    R = grid.resolution
    if values.shape != (R, R, R):
        raise ValueError(f"values must have shape {(R, R, R)}, got {values.shape}")
    below = values < level
    n = R - 1
    count = np.zeros((n, n, n), dtype=np.int8)
    for dx, dy, dz in CORNERS:
        count += below[dx:dx + n, dy:dy + n, dz:dz + n]
    cells = np.argwhere((count > 0) & (count < 8))
    del count, below
    corner_values = np.stack([values[cells[:, 0] + dx, cells[:, 1] + dy, cells[:, 2] + dz]
                              for dx, dy, dz in CORNERS], 1)
    return cells_mesh(cells, corner_values, grid, level, keep_specks=keep_specks)
