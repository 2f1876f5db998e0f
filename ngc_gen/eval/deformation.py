"""Deformation metrics, paper Tables 2-3: relative volume and area change of an edit."""

from __future__ import annotations

import trimesh


def volume_area_change(mesh_before: trimesh.Trimesh, mesh_after: trimesh.Trimesh) -> dict:
    """eps_v = |V' - V| / |V| and eps_a = |A' - A| / A, as fractions (not percent).

    V is trimesh's ``mesh.volume`` (meaningful only for watertight meshes), A the surface area.
    Raises ValueError when the mesh before has zero volume or area.
    """
    v, a = float(mesh_before.volume), float(mesh_before.area)
    v2, a2 = float(mesh_after.volume), float(mesh_after.area)
    if v == 0.0 or a == 0.0:
        raise ValueError(f"mesh before the edit has volume {v} and area {a}; both must be nonzero")
    return {"eps_v": abs(v2 - v) / abs(v), "eps_a": abs(a2 - a) / a}
