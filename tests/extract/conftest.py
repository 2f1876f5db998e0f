import numpy as np
import pytest
import torch

from ngc_gen.geometry import GeneralizedCylinder


def straight_gc(p0, p1, radius, caps=(0.2, 0.2), name="gc"):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": [list(p0), list(p1)]},
        "keys": [{"t": 0.0, "radii": [radius, radius]}], "caps": list(caps)})


def curved_gc(points, radii=(0.25, 0.2), twist=30.0, name="curved"):
    return GeneralizedCylinder.from_dict({
        "name": name, "curve": {"type": "bezier", "points": points}, "up": [0, 0, 1],
        "keys": [{"t": 0.0, "radii": list(radii), "twist": 0.0},
                 {"t": 1.0, "radii": [0.8 * r for r in radii], "twist": twist}],
        "caps": [0.15, 0.1]})


def sphere_sdf(center, radius):
    """World SDF of a sphere: (N, 3) tensor -> (N,)."""
    c = torch.tensor(center, dtype=torch.float64)
    return lambda x: torch.linalg.norm(x.double() - c, dim=1) - radius


def through_gcs(gcs, world_sdfs):
    """sdf_fn(gc_index, rel) evaluating world_sdfs[gc_index] at gcs[gc_index].to_world(rel)."""
    def sdf_fn(g, rel):
        assert rel.dtype == torch.float32 and rel.ndim == 2 and rel.shape[1] == 3
        return world_sdfs[g](gcs[g].to_world(rel.double())).float()
    return sdf_fn


def grid_points(resolution, bound=1.0):
    x = np.linspace(-bound, bound, resolution)
    return np.stack(np.meshgrid(x, x, x, indexing="ij"), -1).reshape(-1, 3)


@pytest.fixture
def sphere_gc():
    """A straight GC along x (radius 0.7) holding a sphere of radius 0.5 centred near 0."""
    gc = straight_gc((-0.6, 0.0, 0.0), (0.6, 0.0, 0.0), 0.7, caps=(0.3, 0.3))
    center, radius = (0.1, 0.05, -0.02), 0.5
    return gc, center, radius, through_gcs([gc], [sphere_sdf(center, radius)])
