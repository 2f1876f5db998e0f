"""Surface meshes of GCs (tube plus caps) for pictures and viewers."""
from __future__ import annotations

import numpy as np
import trimesh

from ngc_gen.geometry import GeneralizedCylinder


def gc_surface(gc: GeneralizedCylinder, n_u: int = 64, n_theta: int = 24) -> trimesh.Trimesh:
    """The GC's boundary max(|u|-1,0)^2 + a^2 + b^2 = 1 as a closed triangle mesh: rings over
    u in [-2, 2] (the caps shrink the ring radius as sqrt(1 - (|u|-1)^2))."""
    psi = np.linspace(np.pi / 2, 0, max(n_u // 4, 3))
    u = np.concatenate([-1 - np.sin(psi)[:-1], np.linspace(-1, 1, max(n_u // 2, 2)),
                        1 + np.sin(psi[::-1])[1:]])
    e = np.clip(np.abs(u) - 1, 0, 1)
    rho = np.sqrt(np.clip(1 - e ** 2, 0, 1))
    th = np.linspace(0, 2 * np.pi, n_theta, endpoint=False)
    U = np.repeat(u, n_theta)
    A = (rho[:, None] * np.cos(th)[None]).ravel()
    B = (rho[:, None] * np.sin(th)[None]).ravel()
    V = np.asarray(gc.to_world(np.stack([U, A, B], 1)))
    n_r = len(u)
    i, j = np.meshgrid(np.arange(n_r - 1), np.arange(n_theta), indexing="ij")
    a = i * n_theta + j
    b = i * n_theta + (j + 1) % n_theta
    c = a + n_theta
    d = b + n_theta
    F = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                        np.stack([a, d, c], -1).reshape(-1, 3)])
    return trimesh.Trimesh(V, F, process=True)


def gcs_surface(gcs: list[GeneralizedCylinder], **kwargs) -> trimesh.Trimesh:
    """All GC surfaces of a shape in one mesh."""
    return trimesh.util.concatenate([gc_surface(g, **kwargs) for g in gcs])


def gc_labels(gcs: list[GeneralizedCylinder]) -> list[tuple[str, np.ndarray]]:
    """(name, (3,) point) per GC, the point at the middle of its curve (normalised arc length
    1/2, relative coordinates (0, 0, 0)): where a picture writes the name an edit program uses."""
    mid = np.zeros((1, 3))
    return [(g.name, np.asarray(g.to_world(mid), dtype=np.float64)[0]) for g in gcs]
