"""extract_mesh against analytic SDFs seen through GCs (sdf_fn built from relative coordinates)."""
import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from ngc_gen.extract import ExtractionResult, SparseSettings, per_gc_rows
from ngc_gen.extract import extract_mesh as _extract_mesh

from .conftest import curved_gc, grid_points, sphere_sdf, straight_gc, through_gcs


def extract_mesh(gcs, sdf_fn, *args, **kwargs):
    """These tests build per-GC fields sdf_fn(j, rel); the extractor takes batched rows."""
    return _extract_mesh(gcs, per_gc_rows(sdf_fn), *args, **kwargs)


def spacing(resolution, bound=1.0):
    return 2 * bound / (resolution - 1)


@pytest.mark.parametrize("bound", [1.0, 0.8])
def test_sphere_matches_analytic_surface_and_is_watertight(sphere_gc, bound):
    gc, center, radius, sdf_fn = sphere_gc
    R = 56
    res = extract_mesh([gc], sdf_fn, R, bound, progress=False)
    assert isinstance(res, ExtractionResult)
    m, h = res.mesh, spacing(R, bound)
    assert len(m.faces) > 1000
    dist = np.abs(np.linalg.norm(m.vertices - center, axis=1) - radius)
    assert dist.max() < 0.05 * h          # measured ~0.01 h: vertices on the sphere
    assert m.is_watertight
    assert m.volume > 0                   # outward normals
    assert abs(m.volume / (4 / 3 * np.pi * radius ** 3) - 1) < 0.01
    assert np.all(np.abs(m.vertices) <= bound)
    # every part of the sphere is there: analytic surface samples are near the mesh
    rng = np.random.default_rng(0)
    d = rng.normal(size=(4000, 3))
    samples = np.asarray(center) + radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    assert cKDTree(m.vertices).query(samples)[0].max() < h


def test_cylinder_inside_gc_is_closed_by_the_gc_boundary():
    """sdf = (sqrt(a^2+b^2) - 0.6) R: an infinite cylinder cut by the GC caps (background)."""
    R_gc = 0.5
    gc = straight_gc((-0.5, 0.1, 0.0), (0.5, 0.1, 0.0), R_gc, caps=(0.2, 0.2))
    res = extract_mesh([gc], lambda g, rel: (torch.sqrt(rel[:, 1] ** 2 + rel[:, 2] ** 2)
                                             - 0.6) * R_gc, 64, progress=False)
    m, h = res.mesh, spacing(64)
    rel = gc.to_relative(m.vertices)
    tube = np.abs(rel[:, 0]) < 0.9
    radial = np.linalg.norm(m.vertices[tube][:, 1:] - [0.1, 0.0], axis=1)
    assert tube.sum() > 500 and np.abs(radial - 0.6 * R_gc).max() < 0.05 * h
    assert m.is_watertight                # closed where the cylinder leaves the GC
    assert m.vertices[:, 0].min() > -0.5 - 0.2 - h and m.vertices[:, 0].max() < 0.5 + 0.2 + h


def mlp_sdf(gcs, seed=0, width=128):
    """A random network over relative coordinates plus a tube term so a surface exists."""
    g = torch.Generator().manual_seed(seed)
    nets = []
    for _ in gcs:
        layers = [torch.nn.Linear(3, width), torch.nn.SiLU(), torch.nn.Linear(width, width),
                  torch.nn.SiLU(), torch.nn.Linear(width, 1)]
        for layer in layers:
            if isinstance(layer, torch.nn.Linear):
                with torch.no_grad():
                    layer.weight.copy_(torch.randn(layer.weight.shape, generator=g)
                                       / layer.weight.shape[1] ** 0.5)
                    layer.bias.copy_(0.1 * torch.randn(layer.bias.shape, generator=g))
        nets.append(torch.nn.Sequential(*layers))

    @torch.no_grad()
    def sdf_fn(i, rel):
        e = torch.clamp(rel[:, 0].abs() - 1, min=0)
        r = torch.sqrt(e * e + rel[:, 1] ** 2 + rel[:, 2] ** 2)
        return 0.2 * (r - 0.65) + 0.03 * nets[i](rel)[:, 0]
    return sdf_fn


def test_prefilter_is_exact_and_evaluates_far_less():
    gcs = [curved_gc([[-0.7, -0.2, 0.0], [-0.2, 0.4, 0.1], [0.3, -0.3, 0.0], [0.7, 0.2, -0.1]]),
           curved_gc([[0.0, -0.7, 0.2], [0.1, 0.0, -0.3], [-0.1, 0.7, 0.2]], radii=(0.2, 0.3),
                     twist=-60.0, name="crossing")]
    sdf_fn, R = mlp_sdf(gcs), 40
    fast = extract_mesh(gcs, sdf_fn, R, method="prefiltered", chunk=8192, keep_values=True,
                        fixed_batch=True, progress=False)
    dense = extract_mesh(gcs, sdf_fn, R, method="dense", chunk=8192, keep_values=True,
                         fixed_batch=True, progress=False)
    assert np.array_equal(fast.values, dense.values)
    assert len(fast.mesh.faces) > 500
    assert np.array_equal(fast.mesh.vertices, dense.mesh.vertices)
    assert np.array_equal(fast.mesh.faces, dense.mesh.faces)
    # the prefilter evaluates exactly the grid points inside each GC, the dense path all of them
    pts = grid_points(R)
    n_inside = sum(int(gc.contains(pts).sum()) for gc in gcs)
    assert fast.stats["n_network_evals"] == n_inside
    assert dense.stats["n_network_evals"] == len(gcs) * R ** 3
    assert fast.stats["n_network_evals"] < 0.2 * dense.stats["n_network_evals"]
    assert fast.stats["n_relative"] < 0.6 * dense.stats["n_relative"]  # bounding boxes only


def test_union_of_overlapping_gcs_takes_the_minimum():
    """Sphere A in a GC along x, sphere B in a GC along y; they overlap in the middle."""
    ga = straight_gc((-0.5, 0, 0), (0.5, 0, 0), 0.5, caps=(0.2, 0.2), name="x")
    gb = straight_gc((0, -0.5, 0), (0, 0.5, 0), 0.5, caps=(0.2, 0.2), name="y")
    sa, sb = sphere_sdf((0.15, 0.0, 0.0), 0.3), sphere_sdf((0.0, 0.15, 0.0), 0.3)
    R = 64
    res = extract_mesh([ga, gb], through_gcs([ga, gb], [sa, sb]), R, method="prefiltered",
                       keep_values=True, progress=False)
    m, h = res.mesh, spacing(R)
    v = torch.from_numpy(m.vertices)
    union = torch.minimum(sa(v), sb(v)).numpy()
    assert np.abs(union).max() < 0.05 * h           # on the union surface, not one sphere
    assert m.is_watertight and m.volume > 0
    # both spheres' exposed parts are present
    rng = np.random.default_rng(1)
    d = rng.normal(size=(6000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    samples = np.concatenate([np.array([0.15, 0, 0]) + 0.3 * d, np.array([0, 0.15, 0]) + 0.3 * d])
    st = torch.from_numpy(samples)
    on_union = np.abs(torch.minimum(sa(st), sb(st)).numpy()) < 1e-9
    assert cKDTree(m.vertices).query(samples[on_union])[0].max() < h
    # the grid value at a point inside both GCs is the min of the two SDFs
    x = np.linspace(-1, 1, R)
    i, j = np.argmin(np.abs(x - 0.1)), np.argmin(np.abs(x - 0.0))
    p = torch.tensor([[x[i], x[i], x[j]]])
    assert res.values[i, i, j] == pytest.approx(float(torch.minimum(sa(p), sb(p))), abs=1e-6)


def test_no_zero_crossing_gives_an_empty_mesh():
    gc = straight_gc((-0.5, 0, 0), (0.5, 0, 0), 0.3)
    res = extract_mesh([gc], lambda g, rel: torch.ones(len(rel)), 32, progress=False)
    assert len(res.mesh.faces) == 0 and len(res.mesh.vertices) == 0
    assert res.stats["n_faces"] == 0 and res.stats["n_network_evals"] > 0
    res = extract_mesh([], lambda g, rel: torch.ones(len(rel)), 32, progress=False)
    assert len(res.mesh.faces) == 0 and res.stats["n_network_evals"] == 0
    # a GC covering the whole grid with a negative SDF: no crossing either
    big = straight_gc((-1.5, 0, 0), (1.5, 0, 0), 3.0)
    res = extract_mesh([big], lambda g, rel: -torch.ones(len(rel)), 16, progress=False)
    assert len(res.mesh.faces) == 0


def test_surface_cut_by_the_grid_stays_inside_the_bound(sphere_gc):
    gc, center, radius, sdf_fn = sphere_gc
    res = extract_mesh([gc], sdf_fn, 40, bound=0.4, progress=False)
    assert len(res.mesh.faces) > 0 and not res.mesh.is_watertight   # cut open by the grid
    assert np.all(np.abs(res.mesh.vertices) <= 0.4)


@pytest.mark.parametrize("method", ["prefiltered", "sparse"])
def test_chunking_and_slabs_do_not_change_the_result(sphere_gc, method):
    gc, _, _, sdf_fn = sphere_gc
    sizes = []

    def recording(g, rel):
        sizes.append(len(rel))
        return sdf_fn(g, rel)
    ref = extract_mesh([gc], sdf_fn, 36, method=method, keep_values=True, progress=False)
    small = extract_mesh([gc], recording, 36, method=method, chunk=1000, slab_points=777,
                         keep_values=True, progress=False)
    assert np.array_equal(ref.values, small.values, equal_nan=True)
    assert max(sizes) == 1000 and min(sizes) < 1000   # no padding: the tail call is short
    assert small.stats["n_network_evals"] == ref.stats["n_network_evals"] == sum(sizes)
    assert small.stats["n_network_rows"] == sum(sizes)
    sizes.clear()
    fixed = extract_mesh([gc], recording, 36, method=method, chunk=1000, fixed_batch=True,
                         progress=True, device="cpu", keep_values=True)
    assert set(sizes) == {1000}                     # exactness mode: fixed batches, tail padded
    assert fixed.stats["n_network_rows"] == 1000 * len(sizes) > fixed.stats["n_network_evals"]
    assert np.array_equal(ref.values, fixed.values, equal_nan=True)


def chamfer(a, b):
    return cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean()


def test_sparse_equals_prefiltered_on_two_bodies_and_a_steep_field(sphere_gc):
    gc, center, radius, _ = sphere_gc
    R = 64
    # a big sphere and a small one that fits between coarse points (no corner sign change)
    big, small = sphere_sdf(center, radius), sphere_sdf((-0.45, 0.3, 0.2), 0.05)
    sdf_fn = through_gcs([gc], [lambda x: torch.minimum(big(x), small(x))])
    full = extract_mesh([gc], sdf_fn, R, method="prefiltered", progress=False)
    fast = extract_mesh([gc], sdf_fn, R, progress=False)
    assert full.mesh.body_count == 2
    assert np.array_equal(full.mesh.vertices, fast.mesh.vertices)
    assert np.array_equal(full.mesh.faces, fast.mesh.faces)
    assert fast.stats["n_network_evals"] < 0.6 * full.stats["n_network_evals"]
    assert sum(lv["network_evals"] for lv in fast.stats["levels"]) \
        + fast.stats["completion_network_evals"] + fast.stats["repair_network_evals"] \
        == fast.stats["n_network_evals"]

    # a wavy field twice as steep as an SDF: still the same mesh within the Lipschitz margin
    c = torch.tensor(center, dtype=torch.float64)

    def wavy(g, rel):
        x = gc.to_world(rel.double())
        d = torch.linalg.norm(x - c, dim=1) - radius
        return (2.0 * d + 0.05 * torch.sin(14 * x[:, 0]) * torch.sin(11 * x[:, 1])).float()
    full = extract_mesh([gc], wavy, R, method="prefiltered", progress=False)
    fast = extract_mesh([gc], wavy, R, progress=False)
    assert np.array_equal(full.mesh.vertices, fast.mesh.vertices)
    assert np.array_equal(full.mesh.faces, fast.mesh.faces)
    assert fast.mesh.is_watertight


def test_bad_sdf_outputs_and_arguments_raise_clear_errors(sphere_gc):
    gc = sphere_gc[0]
    with pytest.raises(ValueError, match="must return"):
        extract_mesh([gc], lambda g, rel: torch.zeros(len(rel) + 1), 16, progress=False)
    with pytest.raises(ValueError, match="non-finite"):
        extract_mesh([gc], lambda g, rel: torch.full((len(rel),), float("nan")), 16,
                     progress=False)
    with pytest.raises(ValueError, match="background"):
        extract_mesh([gc], lambda g, rel: torch.ones(len(rel)), 16, background=-1.0)
    with pytest.raises(TypeError, match="GeneralizedCylinder"):
        extract_mesh([{"curve": 1}], lambda g, rel: torch.ones(len(rel)), 16)
    with pytest.raises(ValueError, match="method"):
        extract_mesh([gc], lambda g, rel: torch.ones(len(rel)), 16, method="refined")
    with pytest.raises(ValueError, match="smooth"):
        extract_mesh([gc], lambda g, rel: torch.ones(len(rel)), 16, smooth=-0.1)


def test_sparse_finds_a_gc_thinner_than_a_coarse_block():
    """A thin GC between coarse lattice lines contains no coarse point; the sparse path must
    still find its surface, and give the prefiltered mesh."""
    R = 129
    h = spacing(R)
    off = -1 + 30 * h          # midway between coarse lines (step 4 at this resolution)
    gc = straight_gc((-0.4, off, off), (0.4, off, off), 1.5 * h, caps=(0.05, 0.05))
    pts = grid_points(R).reshape(R, R, R, 3)[::4, ::4, ::4].reshape(-1, 3)
    assert not gc.contains(pts).any()

    def tube(g, rel):
        return (torch.sqrt(rel[:, 1] ** 2 + rel[:, 2] ** 2) - 0.8) * 1.5 * h
    full = extract_mesh([gc], tube, R, method="prefiltered", progress=False)
    fast = extract_mesh([gc], tube, R, progress=False)
    assert fast.stats["coarse_step"] == 4
    assert len(full.mesh.faces) > 100
    assert np.array_equal(full.mesh.vertices, fast.mesh.vertices)
    assert np.array_equal(full.mesh.faces, fast.mesh.faces)


def rod_sdf(y, z, x0, x1, radius):
    """World SDF of a capsule along x at (y, z) from x0 to x1."""
    def sdf(x):
        x = x.double()
        t = torch.clamp(x[:, 0], x0, x1)
        return torch.sqrt((x[:, 0] - t) ** 2 + (x[:, 1] - y) ** 2 + (x[:, 2] - z) ** 2) - radius
    return sdf


def test_tracking_grows_the_surface_along_a_rod_no_even_lattice_point_sees():
    """The last level visits only blocks whose corners cross N_i's boundary or come within
    track_near c h of it (`SparseSettings.track`); the rest of the surface is grown from them.
    A rod one cell thick, attached to a sphere along a lattice line between the points of the
    side-2 lattice (0.91 h from them by value), meets no such block: it is found by growth,
    and the mesh is the prefiltered one; track=False visits every block the margin keeps (more
    evaluations, same mesh), and also finds the rod standing apart."""
    gc = straight_gc((-0.6, 0.0, 0.0), (0.6, 0.0, 0.0), 0.7, caps=(0.3, 0.3))
    R = 64
    h = spacing(R)
    y, z = -1 + 33 * h, -1 + 31 * h                  # odd lattice lines: no even point near
    ball, rod = sphere_sdf((0.1, 0.05, -0.02), 0.5), rod_sdf(y, z, 0.0, 0.85, 0.5 * h)
    fn = through_gcs([gc], [lambda x: torch.minimum(ball(x), rod(x))])
    ref = extract_mesh([gc], fn, R, method="prefiltered", progress=False)
    assert ref.mesh.vertices[:, 0].max() > 0.8 and ref.mesh.body_count == 1
    band = extract_mesh([gc], fn, R, settings=SparseSettings.from_yaml(track=False), progress=False)
    fast = extract_mesh([gc], fn, R, progress=False)
    for res in (band, fast):
        assert np.array_equal(res.mesh.vertices, ref.mesh.vertices)
        assert np.array_equal(res.mesh.faces, ref.mesh.faces)
    assert fast.stats["repair_rounds"] >= 5                # the rod came from growth
    assert band.stats["repair_rounds"] <= 1
    assert fast.stats["levels"][-1]["network_evals"] < 0.9 * band.stats["levels"][-1][
        "network_evals"]

    apart = through_gcs([gc], [lambda x: torch.minimum(ball(x), rod_sdf(y, z, 0.7, 0.85,
                                                                          0.5 * h)(x))])
    ref = extract_mesh([gc], apart, R, method="prefiltered", progress=False)
    assert ref.mesh.body_count == 2
    band = extract_mesh([gc], apart, R, settings=SparseSettings.from_yaml(track=False), progress=False)
    assert np.array_equal(band.mesh.faces, ref.mesh.faces)


def test_a_block_inside_another_gcs_deep_block_is_found_at_every_step():
    """`inside_deep` drops a block (any step) lying in a block some GC found deep, and only
    those: a wrong parent key would keep evaluating the inside of the shape (or drop surface)."""
    from ngc_gen.extract.sparse import Keys, inside_deep

    keys = Keys(64)
    deep = {4: keys.encode(np.array([[8, 12, 4], [20, 0, 16]])),      # sorted: 8... < 20...
            2: keys.encode(np.array([[40, 40, 40]]))}
    blocks = np.array([[8, 12, 4], [10, 14, 6], [11, 15, 7],          # in the first step-4 block
                       [12, 12, 4], [8, 16, 4], [7, 12, 4],           # just past it
                       [22, 2, 18], [41, 41, 41], [42, 40, 40], [0, 0, 0]])
    hit = inside_deep(keys.encode(blocks), deep, keys)
    assert hit.tolist() == [True, True, True, False, False, False, True, True, False, False]
    assert not inside_deep(keys.encode(blocks), {4: np.zeros(0, np.int64)}, keys).any()
