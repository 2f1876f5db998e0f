import numpy as np
import pytest

from ngc_gen.geometry import GeneralizedCylinder


def random_walk_points(rng, n_points, step=0.3, max_turn=np.pi / 5):
    """Control points of a gently turning curve: random walk with bounded turning angle."""
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    pts = [rng.uniform(-0.3, 0.3, 3)]
    for _ in range(n_points - 1):
        r = rng.normal(size=3)
        r -= (r @ d) * d
        r /= np.linalg.norm(r)
        ang = rng.uniform(0, max_turn)
        d = np.cos(ang) * d + np.sin(ang) * r
        pts.append(pts[-1] + step * rng.uniform(0.7, 1.3) * d)
    return np.array(pts)


def random_gc_dict(rng, degree=None, kind="bezier"):
    degree = degree or int(rng.integers(1, 6))
    pts = random_walk_points(rng, degree + 1 if kind == "bezier" else int(rng.integers(2, 7)))
    nk = int(rng.integers(1, 4))
    ts = np.sort(rng.choice(np.linspace(0, 1, 11), nk, replace=False))
    keys = [{"t": float(t), "radii": rng.uniform(0.03, 0.08, 2).tolist(),
             "twist": float(rng.uniform(-180, 180))} for t in ts]
    return {"name": f"g{degree}", "curve": {"type": kind, "points": pts.tolist()},
            "keys": keys, "caps": rng.uniform(0.02, 0.1, 2).tolist()}


def inside_rel_samples(rng, n):
    """Relative coordinates uniformly over the inside region (tube + caps), u in [-2, 2]."""
    rel = np.stack([rng.uniform(-2, 2, 4 * n), rng.uniform(-1, 1, 4 * n),
                    rng.uniform(-1, 1, 4 * n)], 1)
    return rel[GeneralizedCylinder.inside_relative(rel)][:n]


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
