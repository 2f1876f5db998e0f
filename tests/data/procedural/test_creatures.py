"""Procedural creatures: determinism, watertight single-piece meshes, the shared GC template,
GC coverage, non-elliptic profiles, and the on-disk dataset (reuse, split)."""
import json
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from ngc_gen.data.annotations import load_annotation
from ngc_gen.data.procedural.creatures import (CREATURE_PARTS, CREATURE_TEMPLATE, KEY_TS, build_creatures,
                                    creature_split, gc_coverage, make_creature, sample_parts)
from ngc_gen.data.errors import DataError
from ngc_gen.data.procedural.implicit import grid_axes, mesh_from_field, profile_envelope, profile_norm
from ngc_gen.geometry import smooth_min
from ngc_gen.data.mesh.io import load_mesh, normalize
from ngc_gen.geometry import GeneralizedCylinder

SEEDS = (0, 1, 2)


pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture(scope="module")
def creatures():
    return {s: make_creature(s, check_samples=0) for s in SEEDS}


def test_same_seed_same_creature(creatures):
    mesh, ann = make_creature(SEEDS[0], check_samples=0)
    ref_mesh, ref_ann = creatures[SEEDS[0]]
    assert np.array_equal(mesh.vertices, ref_mesh.vertices)
    assert np.array_equal(mesh.faces, ref_mesh.faces)
    assert ann == ref_ann


def test_meshes_are_watertight_single_piece_and_normalised(creatures):
    for mesh, _ in creatures.values():
        assert mesh.is_watertight and mesh.is_winding_consistent
        assert len(mesh.split(only_watertight=False)) == 1
        assert mesh.volume > 0  # outward-facing
        lo, hi = mesh.bounds
        assert np.allclose((lo + hi) / 2, 0.0, atol=1e-9)
        assert np.isclose((hi - lo).max() / 2, 0.8)


def test_every_annotation_has_the_template_in_order(creatures):
    for seed, (_, ann) in creatures.items():
        assert set(ann) == {"name", "mesh", "normalize", "gcs"}
        assert ann["normalize"] == {"bound": 0.8}
        assert [g["name"] for g in ann["gcs"]] == list(CREATURE_PARTS)
        for g, tp in zip(ann["gcs"], CREATURE_TEMPLATE):
            # a fixed parameter layout per GC: degree, keys and up are the same in every shape
            assert len(g["curve"]["points"]) == tp.degree + 1
            assert [k["t"] for k in g["keys"]] == list(KEY_TS)
            assert g["up"] == list(tp.up)
            GeneralizedCylinder.from_dict(g)


def test_gcs_cover_the_surface(creatures):
    for seed, (mesh, ann) in creatures.items():
        assert gc_coverage(mesh, ann["gcs"], 200_000, seed=seed) >= 0.999, seed


def test_coverage_check_catches_shrunken_gcs(creatures):
    mesh, ann = creatures[SEEDS[0]]
    gcs = [dict(g, keys=[dict(k, radii=[r * 0.6 for r in k["radii"]]) for k in g["keys"]])
           for g in ann["gcs"]]
    assert gc_coverage(mesh, gcs, 20_000) < 0.9


def test_shapes_differ_across_seeds(creatures):
    extents = [np.ptp(m.vertices, axis=0) for m, _ in creatures.values()]
    legs = [GeneralizedCylinder.from_dict(a["gcs"][CREATURE_PARTS.index("leg_fl")]).length
            for _, a in creatures.values()]
    for i in range(len(SEEDS)):
        for j in range(i + 1, len(SEEDS)):
            assert np.abs(extents[i] - extents[j]).max() > 1e-3
            assert abs(legs[i] - legs[j]) > 1e-3


def test_profile_norm_is_not_an_ellipse():
    theta = np.linspace(0, 2 * np.pi, 721)
    c, s = np.cos(theta), np.sin(theta)
    for p in (2.5, 3.0, 4.0):
        # boundary radius along each direction: the ellipse through the axis points is the unit
        # circle, the superellipse reaches 2^(1/2 - 1/p) on the diagonals
        rho = 1.0 / profile_norm(c, s, p)
        assert np.isclose(rho.max(), 2 ** (0.5 - 1 / p), rtol=1e-4)
        assert np.isclose(rho.min(), 1.0, rtol=1e-6)
        assert rho.max() <= profile_envelope(p) + 1e-9
    rho = 1.0 / profile_norm(c, s, 2.0, lobes=5, lobe_amp=0.1, phase=0.3)
    assert np.isclose(rho.max(), 1.1) and np.isclose(rho.min(), 0.9)
    assert rho.max() <= profile_envelope(2.0, 0.1) + 1e-9


def _non_elliptic_share(mesh, gc_dict, slab=0.15, bins=72):
    """Mid-slab cross-section of `mesh` in the GC's frame: 1/rho^2(theta) of any centred ellipse
    holds only the Fourier harmonics 0 and 2; return the rest's amplitude relative to harmonic 0."""
    gc = GeneralizedCylinder.from_dict(gc_dict)
    pts, _ = trimesh.sample.sample_surface(mesh, 100_000, seed=0)
    rel = gc.to_relative(pts)
    rel = rel[np.abs(rel[:, 0]) < slab]
    R = gc.radii_at(torch.from_numpy((rel[:, 0] + 1) / 2)).numpy()
    y, z = rel[:, 1] * R[:, 0], rel[:, 2] * R[:, 1]
    idx = ((np.arctan2(z, y) + np.pi) / (2 * np.pi) * bins).astype(int) % bins
    count = np.bincount(idx, minlength=bins)
    assert count.min() > 0
    F = np.abs(np.fft.rfft(np.bincount(idx, 1 / (y * y + z * z), bins) / count))
    return float(np.sqrt(F[1] ** 2 + F[3] ** 2 + (F[4:] ** 2).sum()) / F[0])


def test_torso_cross_sections_are_measurably_non_elliptic(creatures):
    # control: an elliptic tube meshed by the same marching-cubes path
    gc_dict = {"name": "c", "curve": {"type": "bezier", "points": [[-0.6, 0, 0], [0.6, 0, 0]]},
               "up": [0, 0, 1], "keys": [{"t": 0, "radii": [0.2, 0.3]}], "caps": [0.2, 0.2]}
    gc = GeneralizedCylinder.from_dict(gc_dict)
    lo = np.array([-0.9, -0.4, -0.4])
    axes, h = grid_axes(lo, -lo, 96)
    rel = gc.to_relative(np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3))
    g = np.sqrt(np.clip(np.abs(rel[:, 0]) - 1, 0, None) ** 2 + rel[:, 1] ** 2 + rel[:, 2] ** 2)
    ellipse = mesh_from_field(((g - 1) * 0.2).reshape([len(a) for a in axes]), lo, h)
    control = _non_elliptic_share(ellipse, gc_dict)
    assert control < 0.005
    for seed, (mesh, ann) in creatures.items():
        share = _non_elliptic_share(mesh, ann["gcs"][0])
        assert share > 0.03 and share > 10 * control, (seed, share, control)


def test_every_part_has_a_non_elliptic_profile():
    for seed in range(20):
        for part in sample_parts(seed):
            assert part.exponent >= 2.3 or part.lobe_amp >= 0.05, (seed, part.name)


def test_smooth_min_stays_within_a_quarter_blend_radius():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-1, 1, 10_000), rng.uniform(-1, 1, 10_000)
    k = 0.3
    m = smooth_min(a, b, k)
    assert np.all(m <= np.minimum(a, b)) and np.all(m >= np.minimum(a, b) - k / 4 - 1e-12)
    far = np.abs(a - b) >= k
    assert np.array_equal(m[far], np.minimum(a, b)[far])


def test_too_coarse_resolution_is_refused():
    with pytest.raises(DataError, match="resolution"):
        make_creature(0, resolution=32)


def test_split_is_deterministic_and_disjoint():
    names = [f"creature_{i:04d}" for i in range(40)]
    a, b = creature_split(names, 3, 0.25), creature_split(names, 3, 0.25)
    assert a == b
    assert not set(a["train"]) & set(a["test"])
    assert sorted(a["train"] + a["test"]) == names and len(a["test"]) == 10
    assert creature_split(names, 4, 0.25) != a
    with pytest.raises(DataError):
        creature_split(names, 0, 1.0)


def test_build_writes_loadable_files_and_reuses_them(tmp_path):
    recs = build_creatures(tmp_path, 3, seed=5, test_fraction=0.34, resolution=64)
    assert [r["name"] for r in recs] == ["creature_0000", "creature_0001", "creature_0002"]
    split = json.loads((tmp_path / "split.json").read_text())
    assert sorted(split["train"] + split["test"]) == [r["name"] for r in recs]
    assert not set(split["train"]) & set(split["test"]) and len(split["test"]) == 1
    assert {r["name"]: r["split"] for r in recs} == {
        n: s for s in ("train", "test") for n in split[s]}
    for r in recs:
        assert r["coverage"] >= 0.999 and r["seconds"] > 0
        ann = load_annotation(r["annotation"])
        assert ann.gc_names == list(CREATURE_PARTS) and ann.bound == 0.8
        mesh = load_mesh(ann.mesh_path)
        assert mesh.is_watertight
        normed, center, scale = normalize(mesh, ann.bound)  # already normalised: identity
        assert np.abs(normed.vertices - mesh.vertices).max() < 1e-6
    mtimes = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("creature_*")}
    again = build_creatures(tmp_path, 3, seed=5, test_fraction=0.34, resolution=64)
    assert all(r["seconds"] == 0.0 for r in again)
    assert [dict(r, seconds=0) for r in again] == [dict(r, seconds=0) for r in recs]
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("creature_*")} == mtimes
    assert not list(tmp_path.glob("*.tmp"))


def test_building_in_worker_processes_gives_the_same_files(tmp_path):
    """The default build spreads the shapes over processes; the files must not depend on it."""
    one = build_creatures(tmp_path / "one", 4, seed=5, resolution=64, workers=1)
    two = build_creatures(tmp_path / "two", 4, seed=5, resolution=64, workers=2)
    assert [dict(r, seconds=0, mesh=0, annotation=0) for r in one] == \
        [dict(r, seconds=0, mesh=0, annotation=0) for r in two]
    for a, b in zip(one, two):
        assert Path(a["mesh"]).read_bytes() == Path(b["mesh"]).read_bytes()
        assert Path(a["annotation"]).read_text() == Path(b["annotation"]).read_text()


def test_only_the_creatures_asked_for_are_built(tmp_path):
    recs = build_creatures(tmp_path, 40, seed=5, resolution=64, only=["creature_0031"])
    assert [r["name"] for r in recs] == ["creature_0031"]
    assert sorted(p.name for p in tmp_path.glob("*.ply")) == ["creature_0031.ply"]
    split = json.loads((tmp_path / "split.json").read_text())
    assert len(split["train"]) + len(split["test"]) == 40  # the split covers every name
    with pytest.raises(DataError, match="creature_0040"):
        build_creatures(tmp_path, 40, seed=5, resolution=64, only=["creature_0040"])
