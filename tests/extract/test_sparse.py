"""Sparse extraction against the reference paths: smooth union, incremental edits through a
FieldCache, batched rows without padding, and (slow) a fitted ant with its thin antennae."""
import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from ngc_gen.eval import mesh_chamfer
from ngc_gen.extract import FieldCache, extract_mesh, per_gc_rows
from ngc_gen.extract import settle
from ngc_gen.extract.marching import CORNERS
from ngc_gen.geometry import GeneralizedCylinder, Key
from ngc_gen.geometry.smooth import smooth_min
from ngc_gen.models import NGCDecoder
from ngc_gen.models import ngc as ngc_module
from ngc_gen.shape import Shape
from tests.edit.conftest import GC_DICTS, make_module

from .conftest import grid_points, sphere_sdf, straight_gc, through_gcs


def same_mesh(a, b) -> bool:
    return np.array_equal(a.vertices, b.vertices) and np.array_equal(a.faces, b.faces)


def tube_rows(gcs, radius=0.65):
    """An exact, row-independent field per GC: a rounded tube in relative coordinates scaled
    by the GC's smallest radius (a value never depends on the other rows of its call)."""
    scale = torch.tensor([min(min(k.radii) for k in g.keys) for g in gcs])

    def rows_fn(gc_index, rel):
        e = torch.clamp(rel[:, 0].abs() - 1, min=0)
        r = torch.sqrt(e * e + rel[:, 1] ** 2 + rel[:, 2] ** 2)
        return ((r - radius) * scale[gc_index]).float()
    return rows_fn


def test_smooth_union_is_the_fold_in_gc_order_on_both_paths():
    ga = straight_gc((-0.5, 0, 0), (0.5, 0, 0), 0.5, caps=(0.2, 0.2), name="x")
    gb = straight_gc((0, -0.5, 0), (0, 0.5, 0), 0.5, caps=(0.2, 0.2), name="y")
    fields = [sphere_sdf((0.15, 0.0, 0.0), 0.3), sphere_sdf((0.0, 0.15, 0.0), 0.3)]
    sdf_fn, R, k = through_gcs([ga, gb], fields), 48, 0.1
    ref = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, method="prefiltered", smooth=k,
                       keep_values=True)
    # the fold by hand: each GC where it contains the grid point, smooth-min in GC order
    pts = grid_points(R)
    acc = np.full(len(pts), np.inf, dtype=np.float32)
    for j, gc in enumerate([ga, gb]):
        inside = gc.contains(pts)
        v = sdf_fn(j, torch.from_numpy(gc.to_relative(pts[inside])).float()).numpy()
        a = acc[inside]
        with np.errstate(invalid="ignore"):
            acc[inside] = np.where(np.isfinite(a), smooth_min(a, v, k), v)
    acc[~np.isfinite(acc)] = ref.stats["background"]
    np.testing.assert_allclose(ref.values.reshape(-1), acc, rtol=0, atol=1e-6)
    sparse = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R, smooth=k)
    assert same_mesh(sparse.mesh, ref.mesh)
    hard = extract_mesh([ga, gb], per_gc_rows(sdf_fn), R)
    assert hard.mesh.volume < sparse.mesh.volume < 1.2 * hard.mesh.volume  # the seam filled


def edits(gcs):
    """One change per kind of GC edit: bend (control point), stretch (reparam), scale (key
    radii), twist (key twist), rigid motion; each touches one GC."""
    body, arm, tail = gcs
    pts = arm.curve.points.copy()
    pts[-1] += [0.1, 0.0, -0.1]
    yield "bend", [body, arm.replace(curve=arm.curve.with_points(pts)), tail]
    yield "stretch", [body.replace(reparam=([0.0, 0.5, 1.0], [0.0, 0.4, 1.0])), arm, tail]
    yield "scale", [body, arm, tail.replace(keys=[Key(k.t, tuple(1.2 * r for r in k.radii),
                                                      k.twist) for k in tail.keys])]
    yield "twist", [body, arm.replace(keys=[Key(k.t, k.radii, k.twist + 40.0)
                                           for k in arm.keys]), tail]
    c, s = np.cos(0.3), np.sin(0.3)
    yield "rigid", [body, arm, tail.transformed(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
                                                np.array([0.02, 0.0, 0.03]))]


def gc_key(gc: GeneralizedCylinder):
    return repr(gc.to_dict())


@pytest.mark.parametrize("network", ["exact field", "decoder"])
def test_incremental_equals_full_reextraction_after_each_kind_of_edit(network):
    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    if network == "decoder":   # a real NGCDecoder; fixed batches make rows batch-independent
        module = make_module()
        rows_fn = Shape(gcs, module.codes.weight[:3], module.decoder).rows
        kw = dict(fixed_batch=True, chunk=4096)
    else:
        rows_fn, kw = tube_rows(gcs), {}
    R = 48
    cache = FieldCache()
    first = extract_mesh(gcs, rows_fn, R, cache=cache, gc_keys=[gc_key(g) for g in gcs], **kw)
    assert first.stats["cache_misses"] == 3 and len(first.mesh.faces) > 500
    for name, edited in edits(gcs):
        full = extract_mesh(edited, rows_fn, R, **kw)
        inc = extract_mesh(edited, rows_fn, R, cache=cache,
                           gc_keys=[gc_key(g) for g in edited], **kw)
        assert inc.stats["cache_hits"] == 2 and inc.stats["cache_misses"] == 1, name
        assert same_mesh(inc.mesh, full.mesh), name
        assert not same_mesh(inc.mesh, first.mesh), name
        assert inc.stats["n_network_evals"] < full.stats["n_network_evals"], name
    # the unedited shape again: every GC from the cache, no network call at all
    again = extract_mesh(gcs, rows_fn, R, cache=cache, gc_keys=[gc_key(g) for g in gcs], **kw)
    assert again.stats["n_network_evals"] == 0 and same_mesh(again.mesh, first.mesh)


def test_rows_go_to_the_network_once_batched_across_gcs_and_unpadded():
    module = make_module()
    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    inner = Shape(gcs, module.codes.weight[:3], module.decoder).rows
    calls = []

    def rows_fn(gc_index, rel):
        calls.append((gc_index.clone(), rel.clone()))
        return inner(gc_index, rel)
    cache = FieldCache()
    res = extract_mesh(gcs, rows_fn, 64, chunk=5000, cache=cache,
                       gc_keys=[gc_key(g) for g in gcs])
    n_rows = sum(len(r) for _, r in calls)
    assert n_rows == res.stats["n_network_evals"] == res.stats["n_network_rows"]
    assert max(len(r) for _, r in calls) <= 5000
    assert any(len(torch.unique(g)) > 1 for g, _ in calls)      # one call, several GCs
    # every row is a distinct point inside its GC, evaluated once: no padding, no repeats
    for j, gc in enumerate(gcs):
        rel = torch.cat([r[g == j] for g, r in calls]).numpy()
        assert len(np.unique(rel, axis=0)) == len(rel)
        assert np.all(GeneralizedCylinder.inside_relative(rel.astype(np.float64)) | (
            np.abs(np.abs(rel[:, 0]) - 2) < 1e-6))
    stored = sum(int(np.isfinite(cache.get(gc_key(g), 64, 1.0)[0].f).sum()) for g in gcs)
    assert n_rows == stored
    # the batched decoder call equals the per-sample forward up to float rounding
    g, r = calls[0]
    with torch.no_grad():
        ref = module.decoder(module.codes.weight[:3][g], r)
    torch.testing.assert_close(inner(g, r), ref, atol=1e-5, rtol=0)


def test_decoder_rows_do_not_depend_on_the_rows_sharing_their_call(monkeypatch):
    """Sparse and reference paths send a point to the network in different calls; its value
    must not change (BLAS and vectorised kernels round a ragged tail differently: sdf_rows
    pads its blocks to ROWS_ALIGN rows)."""
    torch.manual_seed(0)
    dec = NGCDecoder(16, 16, 32, 2, 64, 3, 4).eval()
    codes = torch.randn(5, 16)
    g, rel = torch.randint(0, 5, (600,)), torch.rand(600, 3) * 2 - 1

    def split(sizes):
        out, s = [], 0
        for n in sizes:
            out.append(dec.sdf_rows(codes, g[s:s + n], rel[s:s + n]))
            s += n
        return torch.cat(out)
    sizes = [1, 2, 3, 5, 7, 17, 33, 100, 432]
    with torch.inference_mode():
        whole = dec.sdf_rows(codes, g, rel)
        assert torch.equal(split(sizes), whole)
        assert torch.equal(split(sizes[::-1]), whole)
        monkeypatch.setattr(ngc_module, "ROWS_ALIGN", 1)     # the property needs the padding
        assert not torch.equal(split(sizes), dec.sdf_rows(codes, g, rel))


def brute_settle(f, m, tau, r_min, reach):
    """The settling rule of ngc_gen.extract.settle written out per point with numpy."""
    state = np.zeros((len(f), 27), dtype=np.uint8)
    for j, p in enumerate(settle.HALF):
        ps = [o for o, c in enumerate(CORNERS) if np.all((p == 1) | (2 * c == p))]
        k = int((p == 1).sum())
        fp, mp = f[:, ps].astype(np.float64), m[:, ps].astype(np.float64)
        inside = mp <= 1.0
        if k == 0:
            neg = inside[:, 0] & (f[:, ps[0]] < np.float32(tau))
            pos = ~inside[:, 0] | (f[:, ps[0]] >= 0)
            state[:, j] = neg * settle.CAN_NEG | pos * settle.CAN_POS | settle.SURE
            continue
        depth = (1 - np.sqrt(np.minimum(mp, 1.0))) * r_min
        above = np.all(inside & (fp > tau + reach[k]), 1)
        deep = np.all(inside & (fp < -reach[k]) & (depth > reach[k]), 1)
        state[:, j] = np.where(above & ~deep, settle.CAN_POS | settle.SURE,
                               np.where(deep & ~above, settle.CAN_NEG | settle.SURE,
                                        settle.CAN_NEG | settle.CAN_POS))
    return state


def test_last_level_settling_and_cell_decisions_match_the_rule():
    rng = np.random.default_rng(0)
    n, tau, r_min = 4000, 0.01, 0.3
    reach = 1.5 * 0.02 * np.sqrt(np.arange(4.0))
    # smooth-ish blocks: a level per block plus small corner noise, a few corners outside
    f = (rng.uniform(-0.15, 0.15, (n, 1)) + rng.normal(0, 0.01, (n, 8))).astype(np.float32)
    m = np.where(rng.random((n, 8)) < 0.03, rng.choice([1.5, np.inf], (n, 8)),
                 rng.choice([0.05, 0.5, 0.99], (n, 8))).astype(np.float32)
    state = np.empty((n, 27), dtype=np.uint8)
    settle.settle_points(f, m, np.float32(tau), tau, r_min, reach, settle.PARENTS,
                         settle.N_PARENTS, settle.N_ODD, state)
    ref = brute_settle(f, m, tau, r_min, reach)
    np.testing.assert_array_equal(state, ref)
    assert 0.2 < np.mean(state[:, settle.N_ODD > 0] & settle.SURE > 0) < 0.8
    # cells: decided at once where every corner is settled, else from the evaluated values
    idx = rng.integers(0, 6, (n, 3))
    status = np.empty((n, 8), dtype=np.uint8)
    settle.cell_status(state, idx, 5, CORNERS, settle.CELL, status)
    corners = state[:, settle.CELL]                                  # (n, 8 cells, 8 corners)
    can = (np.any(corners & settle.CAN_NEG, 2) & np.any(corners & settle.CAN_POS, 2))
    inside_grid = np.all(idx[:, None, :] + CORNERS[None] <= 5, 2)
    sure = np.all(corners & settle.SURE, 2)
    np.testing.assert_array_equal(status == settle.KEEP, inside_grid & can & sure)
    np.testing.assert_array_equal(status == settle.UNDECIDED, inside_grid & can & ~sure)
    need = np.zeros((n, 27), dtype=bool)
    settle.needed_points(state, status, settle.CELL, need)
    und = status == settle.UNDECIDED
    for o in range(8):           # unsettled corners of undecided cells, nothing else
        c = settle.CELL[o]
        assert np.all(need[und[:, o]][:, c] >= (state[und[:, o]][:, c] & settle.SURE == 0))
    assert not np.any(need & (state & settle.SURE > 0))


def test_sparse_equals_prefiltered_with_a_decoder_and_settling_saves_evaluations(monkeypatch):
    """A real NGCDecoder without fixed batches: the sparse mesh is the prefiltered one, bit for
    bit; settling new points of the last level from their block corners saves network rows
    (the same extraction with nothing settled evaluates more and gives the same mesh)."""
    module = make_module()
    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    rows_fn = Shape(gcs, module.codes.weight[:3], module.decoder).rows
    R = 97
    ref = extract_mesh(gcs, rows_fn, R, method="prefiltered")
    fast = extract_mesh(gcs, rows_fn, R)
    assert len(ref.mesh.faces) > 1000
    assert same_mesh(fast.mesh, ref.mesh)
    assert fast.stats["n_network_evals"] < 0.8 * ref.stats["n_network_evals"]
    assert fast.stats["levels"][-1]["settled"] > 0
    settle_points = settle.settle_points

    def nothing_settled(f, m, *args):
        state = args[-1]
        settle_points(f, m, *args)
        state[:, settle.N_ODD > 0] = settle.CAN_NEG | settle.CAN_POS
    monkeypatch.setattr(settle, "settle_points", nothing_settled)
    slow = extract_mesh(gcs, rows_fn, R)
    assert slow.stats["levels"][-1]["settled"] == 0 and same_mesh(slow.mesh, ref.mesh)
    saved = slow.stats["levels"][-1]["network_evals"] - fast.stats["levels"][-1]["network_evals"]
    assert saved > 0.2 * slow.stats["levels"][-1]["network_evals"]


def test_cache_and_arguments_are_checked():
    gcs = [GeneralizedCylinder.from_dict(d) for d in GC_DICTS]
    fn = tube_rows(gcs)
    with pytest.raises(ValueError, match="together"):
        extract_mesh(gcs, fn, 16, cache=FieldCache())
    with pytest.raises(ValueError, match="one key per GC"):
        extract_mesh(gcs, fn, 16, cache=FieldCache(), gc_keys=["a"])
    with pytest.raises(ValueError, match="sparse"):
        extract_mesh(gcs, fn, 16, method="dense", cache=FieldCache(), gc_keys=[1, 2, 3])
    with pytest.raises(TypeError, match="hashable"):
        extract_mesh(gcs, fn, 16, cache=FieldCache(), gc_keys=[[1], [2], [3]])


@pytest.mark.slow
def test_fitted_ant_sparse_equals_prefiltered_including_antennae(tmp_path):
    """A short real fit of the ant (15 GCs, antennae a few voxels thick): the sparse mesh has
    the prefiltered one's surface (Chamfer < 1e-6 against the surface) and its antennae."""
    from ngc_gen.app.runtime.config import compose_config
    from ngc_gen.app.stages.fit import run_fit
    from ngc_gen.lit.checkpoint import load_autodecoder
    from ngc_gen.shape import autodecoder_mesh as extract_shape
    from ngc_gen.shape import recorded_gcs as shape_gcs

    cfg = compose_config(overrides=[
        "stage=fit", "data=ant", "model=small", "trainer.max_steps=400", "extract.resolution=48",
        f"run_dir={tmp_path}", "trainer.enable_progress_bar=false", "logger=csv",
        f"prepare.cache_dir={tmp_path / 'cache'}"])
    run_fit(cfg)
    module = load_autodecoder(tmp_path / "checkpoints" / "last.ckpt")
    gcs = shape_gcs(module.hparams.meta["shapes"][0])
    for R in (128, 256):
        ref = extract_shape(module, 0, R, method="prefiltered").mesh
        fast = extract_shape(module, 0, R).mesh
        # surface distance, not sample-to-sample: one face more or less moves every later
        # sample of the DeepSDF estimator (~1e-5, two samplings of one mesh ~1e-4); a short fit
        # holds single-voxel floaters 5-17x steeper than the Lipschitz margin, a few of which
        # the sparse path may miss (~1e-7 measured)
        assert mesh_chamfer(fast, ref) < 1e-6
        for name in ("antenna_l", "antenna_r"):
            gc = next(g for g in gcs if g.name == name)
            n_ref = gc.contains(ref.vertices).sum()
            assert n_ref > 100 and gc.contains(fast.vertices).sum() >= 0.98 * n_ref
