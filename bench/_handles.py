"""Handle edits measured two ways, shared by bench/deform.py and bench/autogc.py: a `Case`
drags the vertices of one GC region by a rigid motion (a bend or a twist); `run_case` solves it
with NGC's `deform_by_handles` and with libigl ARAP on the same handle and fixed vertices, and
returns both meshes' volume and area change, times and handle errors."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

BOUND = 1.25            # extraction grid [-1.25, 1.25]^3: bent bars leave the unit cube
FIXED_T = 0.1           # the handle GC's own start region that stays (t <= 0.1)


def rotation(axis, degrees) -> np.ndarray:
    import numpy as np
    from scipy.spatial.transform import Rotation

    a = np.asarray(axis, float)
    return Rotation.from_rotvec(a / np.linalg.norm(a) * math.radians(degrees)).as_matrix()


@dataclass
class Case:
    """A handle drag: the vertices of `gc` over t in `at` move by a rigid motion.

    bend: the piece of the GC between t = FIXED_T and t = at[0] is wrapped onto a circular arc
    of `degrees` turning toward `up` (its chord direction d, the arc in the plane of d and up),
    and the handle region follows the arc's end rigidly: a constant-curvature bend, the
    motion an arc-length preserving deformation can meet. twist: the handles turn about the
    GC's axis (its chord)."""

    name: str
    shape: str
    gc: str
    kind: str                 # bend | twist
    degrees: float
    at: tuple = (0.9, 1.0)
    up: tuple = (0.0, 0.0, 1.0)
    picture: bool = False

    def motion(self, gc) -> tuple[np.ndarray, np.ndarray]:
        """(R, t): handle targets are H @ R.T + t."""
        import numpy as np

        p_f, p_h = gc.to_world(np.array([[2 * FIXED_T - 1, 0, 0], [2 * self.at[0] - 1, 0, 0]]))
        chord = p_h - p_f
        d = chord / np.linalg.norm(chord)
        if self.kind == "twist":
            return rotation(d, self.degrees), p_h - rotation(d, self.degrees) @ p_h
        if self.kind != "bend":
            raise ValueError(self.kind)
        n = np.asarray(self.up, float) - (np.asarray(self.up, float) @ d) * d
        n /= np.linalg.norm(n)
        th = math.radians(self.degrees)
        rho = np.linalg.norm(chord) / th
        R = rotation(np.cross(d, n), self.degrees)  # turns d toward n
        P = p_f + rho * math.sin(th) * d + rho * (1 - math.cos(th)) * n
        return R, P - R @ p_h


def constraints(case: Case, gcs, V):
    """Handle and fixed vertex indices of the input mesh (disjoint). The handle GC's part is
    the vertices inside it or, outside every GC, nearest to it; the fixed vertices are the rest
    of the mesh plus the part's start region t <= FIXED_T."""
    import numpy as np

    from ngc_gen.edit.program import region_mask

    rel = np.stack([g.to_relative(V) for g in gcs])  # (K, N, 3)
    measure = np.clip(np.abs(rel[..., 0]) - 1, 0, None) ** 2 + rel[..., 1] ** 2 + rel[..., 2] ** 2
    k = [g.name for g in gcs].index(case.gc)
    gc = gcs[k]
    part = (measure[k] <= 1.0) | (measure.argmin(0) == k)
    handle = part & region_mask(gc, V, case.at)
    fixed = (~part | region_mask(gc, V, (0.0, FIXED_T))) & ~handle
    return np.flatnonzero(handle), np.flatnonzero(fixed)


def arap(V, F, handle, fixed, targets, iters: int) -> tuple[np.ndarray, float]:
    """libigl ARAP with handles moved and fixed vertices pinned; one pinned vertex for every
    connected piece without a constraint. Returns (deformed vertices, seconds)."""
    import numpy as np
    import igl
    import trimesh

    t0 = time.perf_counter()
    b = np.concatenate([handle, fixed])
    bc = np.concatenate([targets, V[fixed]])
    labels = trimesh.graph.connected_component_labels(trimesh.Trimesh(V, F, process=False)
                                                      .face_adjacency, node_count=len(F))
    vlab = np.full(len(V), -1)
    vlab[F.reshape(-1)] = np.repeat(labels, 3)
    free = sorted(set(vlab[vlab >= 0].tolist()) - set(vlab[b].tolist()))
    extra = np.array([np.flatnonzero(vlab == p)[0] for p in free], dtype=np.int64)
    b = np.concatenate([b, extra]).astype(np.int64)
    bc = np.concatenate([bc, V[extra]]) if len(extra) else bc
    data = igl.ARAPData()
    data.max_iter = int(iters)
    igl.arap_precomputation(V, F, 3, b, data)
    U = igl.arap_solve(np.ascontiguousarray(bc), data, V.copy())
    return U, time.perf_counter() - t0


def edit_to_mesh(case: Case, shape, gcs, R, t, handles, targets, fixed_pts, resolution: int,
                 arap_iters: int, undeformed: dict, arap_at: int = 256):
    """Seconds from handle targets to the edited mesh at `resolution`, the interactive loop:
    the handle solve plus the incremental extraction (the undeformed shape was extracted
    before, untimed, so its per-GC values sit in shape.cache and only the GCs the solve moved
    are evaluated again); the solve gets the same handles as the case. At `arap_at` also
    returns (ARAP seconds, vertex count): libigl ARAP with the same handle region and motion
    on that undeformed NGC mesh (a mesh of NGC's vertex count), else None."""
    import numpy as np
    import torch

    from ngc_gen.edit import deform_by_handles

    key = (case.shape, resolution)
    with torch.inference_mode():
        if key not in undeformed:
            undeformed[key] = shape.mesh(resolution, BOUND).mesh
        before = undeformed[key]
        t0 = time.perf_counter()
        new = deform_by_handles(gcs, handles, targets, fixed_pts)
        shape.replaced(gcs=new).mesh(resolution, BOUND)
        seconds = time.perf_counter() - t0
    arap_matched = None
    if resolution == arap_at:
        V = np.asarray(before.vertices, dtype=np.float64)
        F = np.asarray(before.faces, dtype=np.int64)
        handle, fixed = constraints(case, gcs, V)
        _, arap_s = arap(V, F, handle, fixed, V[handle] @ R.T + t, arap_iters)
        arap_matched = (arap_s, int(len(V)))
    return seconds, arap_matched


def run_case(case: Case, module, shape_index: dict, inputs: dict, resolution: int,
             arap_iters: int, undeformed: dict, matched: tuple = ()) -> dict:
    import numpy as np
    import torch
    import trimesh

    from ngc_gen.edit import deform_by_handles
    from ngc_gen.edit.ops import curve_points_at
    from ngc_gen.eval import volume_area_change
    from ngc_gen.shape import Shape, recorded_gcs

    meta = module.hparams.meta["shapes"][shape_index[case.shape]]
    gcs = recorded_gcs(meta)
    codes = module.codes.weight[meta["code_offset"]:meta["code_offset"] + meta["n_codes"]].detach()
    V, F = inputs[case.shape]
    handle, fixed = constraints(case, gcs, V)
    gc = next(g for g in gcs if g.name == case.gc)
    R, t = case.motion(gc)
    targets = V[handle] @ R.T + t

    # one Shape per input shape, so its FieldCache carries the undeformed values across cases
    shape = undeformed.setdefault(("shape", case.shape),
                                  Shape(gcs, codes, module.decoder, name=case.shape))
    with torch.no_grad():
        if case.shape not in undeformed:
            undeformed[case.shape] = shape.mesh(resolution, BOUND).mesh
        before = undeformed[case.shape]
        # the fixed region for NGC: the fixed vertices plus the skeletons of the other GCs (a
        # part rooted inside the fixed body, like a tail in a torso, is far from its surface)
        skeleton = [curve_points_at(g, np.linspace(0, 1, 33)) for g in gcs if g.name != case.gc]
        fixed_pts = np.concatenate([V[fixed], *skeleton])
        t0 = time.perf_counter()
        new, info = deform_by_handles(gcs, V[handle], targets, fixed_pts, return_info=True)
        solve_s = time.perf_counter() - t0
        after = shape.replaced(gcs=new).mesh(resolution, BOUND).mesh
        ngc_s = time.perf_counter() - t0
    # where the handle GC carries the handle vertices (their relative coordinates)
    new_gc = next(g for g in new if g.name == case.gc)
    carried = new_gc.to_world(gc.to_relative(V[handle]))
    ngc = {**volume_area_change(before, after), "time_s": ngc_s, "solve_s": solve_s,
           "handle_err": float(np.linalg.norm(carried - targets, axis=1).max()),
           "bent": sorted(info.bent), "followers": sorted(info.followers)}

    for res in matched:  # edit-to-mesh at 128 / 256, ARAP on a mesh of NGC's vertex count
        ngc[f"edit_to_mesh_s_{res}"], arap_matched = edit_to_mesh(
            case, shape, gcs, R, t, V[handle], targets, fixed_pts, res, arap_iters, undeformed)
        if arap_matched is not None:
            ngc["arap_s_matched"], ngc["arap_matched_vertices"] = arap_matched

    U, arap_s = arap(V, F, handle, fixed, targets, arap_iters)
    m0 = trimesh.Trimesh(V, F, process=False)
    m1 = trimesh.Trimesh(U, F, process=False)
    res = {"name": case.name, "ngc": ngc,
           "arap": {**volume_area_change(m0, m1), "time_s": arap_s,
                    "handle_err": float(np.linalg.norm(U[handle] - targets, axis=1).max())},
           "n_handles": int(len(handle)), "n_fixed": int(len(fixed)), "n_vertices": int(len(V)),
           "degrees": case.degrees, "kind": case.kind, "gc": case.gc, "shape": case.shape}
    res["_meshes"] = (m0, before, after, m1)
    res["_focus"] = (np.minimum(gc.bounds()[0], new_gc.bounds()[0]),
                     np.maximum(gc.bounds()[1], new_gc.bounds()[1]))
    return res
