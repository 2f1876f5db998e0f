"""Procedural creatures: cartoon quadrupeds standing in a T-pose-like stance, with ground-truth GCs.

Our stand-in for RaBit (NGC paper Sec. 4.4): every shape has the same template of named GCs
(``CREATURE_TEMPLATE``), so a shape decoder can map one latent to all of them. Each part is an
implicit solid around a Bezier skeleton with a smoothly varying radius profile and a
*non-elliptic* cross-section (a lobed superellipse, ``implicit.profile_norm``), so a classic
elliptic GC cannot represent it: the neural SDF inside the GC has real work to do.

The parts are merged by a polynomial smooth union, sampled on a grid (each part only inside its
GC's box), meshed by marching cubes into one watertight piece, and normalised. The annotation's
GCs share each part's skeleton and frames, with radii and caps grown to enclose the part's
profile, the smooth-union fillets and the marching-cubes error, so they cover the surface.

Frame: z up, x forward (the head is at +x), y to the creature's left; feet near the lowest z.
Everything is generated in a design frame and then mapped by the similarity that
``mesh_io.normalize`` would apply, so the mesh's bounding box is centred with its longest side
spanning [-0.8, 0.8]: normalising again is the identity (up to float rounding).
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml

from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError
from ngc_gen.data.procedural.implicit import (block_points, grid_axes, mesh_from_field,
                                              profile_norm)
from ngc_gen.data.annotations import rounded_gc_dict, similar_gc_dict
from ngc_gen.data.mesh.io import normalize
from ngc_gen.data.workers import map_shapes
from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis, smooth_min

# the template and the random parts, also importable from here
from .creature_parts import (CREATURE_PARTS, CREATURE_TEMPLATE, Part, PartTemplate,  # noqa: F401
                             sample_parts)

#: Bump when the generator changes: built datasets with another version are rebuilt.
CREATURES_VERSION = 1
BOUND = 0.8
#: Normalised arc lengths of the annotation key frames, the same for every GC and shape.
KEY_TS = (0.0, 0.25, 0.5, 0.75, 1.0)
MIN_COVERAGE = 0.999
#: Coarser grids can lose thin parts (ears, tail tips): measured, 48 split one creature in two.
MIN_RESOLUTION = 64


# ---- ground-truth GCs -----------------------------------------------------------------------
def _enclosing_gc(part: Part, margin: float) -> dict:
    """A GC dict on the part's skeleton and frames that encloses the region where the part's
    field is <= `margin` (field units = world length at the part's mean radius).

    There the gauge g <= 1 + eps(t), eps = margin / sqrt(r_y r_z), so the offset in the frame is
    within envelope * (1 + eps) * r(t), and past an end within (1 + eps) * cap. Key radii take the
    maximum of that bound over both neighbouring key intervals, so the GC's lerped radii bound
    the smooth profile everywhere."""
    t = np.linspace(0.0, 1.0, 1025)
    r = part.radii(t)
    eps = margin / np.sqrt(r[:, 0] * r[:, 1])
    bound = part.envelope * r * (1.0 + eps)[:, None] * 1.002  # 1.002: sampling slack
    keys = []
    for i, tk in enumerate(KEY_TS):
        lo_t = KEY_TS[max(i - 1, 0)]
        hi_t = KEY_TS[min(i + 1, len(KEY_TS) - 1)]
        sel = (t >= lo_t - 1e-9) & (t <= hi_t + 1e-9)
        twist = part.twist[0] + (part.twist[1] - part.twist[0]) * tk
        keys.append({"t": tk, "radii": bound[sel].max(0).tolist(), "twist": twist})
    caps = [part.caps[0] * (1.0 + eps[0]) * 1.002, part.caps[1] * (1.0 + eps[-1]) * 1.002]
    return {"name": part.name, "curve": {"type": "bezier", "points": part.points.tolist()},
            "up": list(part.up), "keys": keys, "caps": caps}


def _part_field(part: Part, gc: GeneralizedCylinder, points: np.ndarray) -> np.ndarray:
    """The part's field at world points (M, 3): (g - 1) * sqrt(r_y r_z), g the profile gauge
    in the GC's relative coordinates (a distance-like value near the surface)."""
    rel = gc.to_relative(points)
    u = rel[:, 0]
    t = np.clip((u + 1.0) * 0.5, 0.0, 1.0)
    R = gc.radii_at(torch.from_numpy(t)).numpy()  # the GC's own radii: back to world offsets
    r = part.radii(t)
    alpha = rel[:, 1] * R[:, 0] / r[:, 0]
    beta = rel[:, 2] * R[:, 1] / r[:, 1]
    # past an end: distance along the end tangent over the part's own cap length
    ext = (np.clip(-1.0 - u, 0.0, None) * gc.caps[0] / part.caps[0]
           + np.clip(u - 1.0, 0.0, None) * gc.caps[1] / part.caps[1])
    n = profile_norm(alpha, beta, part.exponent, part.lobes, part.lobe_amp, part.phase)
    return (np.sqrt(ext * ext + n * n) - 1.0) * np.sqrt(r[:, 0] * r[:, 1])


def _bezier_points(points: np.ndarray, samples: int = 257) -> np.ndarray:
    """Points (samples, 3) on the Bezier curve with control points `points`."""
    return bernstein_basis(len(points) - 1, np.linspace(0.0, 1.0, samples)) @ points


def gc_box(d: dict) -> tuple[np.ndarray, np.ndarray]:
    """A conservative axis-aligned box of a Bezier GC dict: the curve (densely sampled) grown by
    its largest radius or cap and the sampling step. Cheaper than building the GC."""
    pts = np.asarray(d["curve"]["points"], np.float64)
    c = _bezier_points(pts)
    step = float(np.linalg.norm(np.diff(c, axis=0), axis=1).max())
    m = max(max(max(k["radii"]) for k in d["keys"]), max(d["caps"])) + step
    return c.min(0) - m, c.max(0) + m


def _union_contains(gcs, boxes, points: np.ndarray) -> np.ndarray:
    """(N,) bool: points inside the union of GCs, each tested only inside its box and only on
    points not yet found inside."""
    inside = np.zeros(len(points), dtype=bool)
    for gc, (lo, hi) in zip(gcs, boxes):
        todo = np.flatnonzero(~inside & ((points >= lo) & (points <= hi)).all(1))
        if len(todo):
            inside[todo] = GeneralizedCylinder.inside_relative(gc.to_relative(points[todo]))
    return inside


def gc_coverage(mesh: trimesh.Trimesh, gcs, samples: int = 200_000, seed: int = 0) -> float:
    """Share of `samples` area-uniform surface points of `mesh` inside the union of `gcs`
    (GC dicts, as in an annotation)."""
    objs = [GeneralizedCylinder.from_dict(d) for d in gcs]
    pts, _ = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    return float(_union_contains(objs, [gc_box(d) for d in gcs], pts).mean())


def make_creature(seed: int, resolution: int = 128, name: str | None = None,
                  check_samples: int = 200_000) -> tuple[trimesh.Trimesh, dict]:
    """One creature from `seed`: (watertight single-piece mesh, annotation dict).

    The annotation follows docs/gcs.md (name, mesh = '<name>.ply', normalize {bound: 0.8}, gcs in
    ``CREATURE_PARTS`` order) and is already in the normalised frame of the mesh. `resolution`
    is the number of grid cells along the creature's longest side. Checks the surface coverage
    of the GCs on `check_samples` surface points (0 skips it) and raises DataError below 0.999.
    Same seed and resolution give identical vertices."""
    mesh, annotation, _ = _make(seed, resolution, name, check_samples)
    return mesh, annotation


def _make(seed: int, resolution: int, name: str | None, check_samples: int):
    """`make_creature` that also returns the measured coverage (None if not checked)."""
    if int(resolution) < MIN_RESOLUTION:
        raise DataError(f"resolution {resolution} is too coarse for the thin parts (ears, tail)",
                        field="resolution", fix=f"use at least {MIN_RESOLUTION} (default 128)")
    return _make_parts(int(seed), int(resolution), name, int(check_samples))


def _make_parts(seed: int, resolution: int, name: str | None, check_samples: int):
    """Sample the parts, fit their GCs, evaluate the smooth union on the grid, mesh, normalise
    and check coverage."""
    name = name or f"creature_{seed}"
    parts = sample_parts(seed)
    index = {p.name: i for i, p in enumerate(CREATURE_TEMPLATE)}
    # the fillet a part makes with the union lies within blend/4 of it in field units; a parent
    # also hosts its children's fillets
    blend = np.array([p.blend for p in parts])
    for tp in CREATURE_TEMPLATE:
        if tp.parent is not None:
            blend[index[tp.parent]] = max(blend[index[tp.parent]], blend[index[tp.name]])
    boxes0 = [gc_box(_enclosing_gc(p, 0.25 * b)) for p, b in zip(parts, blend)]
    _, voxel = grid_axes(np.min([b[0] for b in boxes0], 0), np.max([b[1] for b in boxes0], 0),
                         resolution)
    # marching cubes puts the surface within a fraction of a voxel of the zero set: grow the GCs
    # by half a voxel more
    gc_dicts = [_enclosing_gc(p, 0.25 * b + 0.5 * voxel) for p, b in zip(parts, blend)]
    gcs = [GeneralizedCylinder.from_dict(d) for d in gc_dicts]
    boxes = [gc_box(d) for d in gc_dicts]
    pad = 2.0 * blend.max() + 3.0 * voxel
    lo = np.min([b[0] for b in boxes], 0) - pad
    hi = np.max([b[1] for b in boxes], 0) + pad
    axes, voxel = grid_axes(lo, hi, resolution)
    field = np.full([len(a) for a in axes], 10.0)
    for part, gc, (blo, bhi) in zip(parts, gcs, boxes):
        # outside the padded box the part is farther than its blend radius: no effect
        k = part.blend
        sl, pts = block_points(axes, blo - (1.5 * k + 2 * voxel), bhi + (1.5 * k + 2 * voxel))
        f = _part_field(part, gc, pts).reshape(field[sl].shape)
        field[sl] = smooth_min(field[sl], f, k)
    mesh = mesh_from_field(field, lo, voxel)

    mesh, center, scale = normalize(mesh, BOUND)
    annotation = {"name": name, "mesh": f"{name}.ply", "normalize": {"bound": BOUND},
                  "gcs": [rounded_gc_dict(similar_gc_dict(d, center, scale)) for d in gc_dicts]}
    coverage = None
    if check_samples:
        # relative coordinates are invariant under the similarity: test in the design frame
        pts, _ = trimesh.sample.sample_surface(mesh, check_samples, seed=seed)
        coverage = float(_union_contains(gcs, boxes, pts / scale + center).mean())
        if coverage < MIN_COVERAGE:
            raise DataError(f"creature seed {seed}: its GCs cover only {coverage:.5f} of the "
                            f"surface (need {MIN_COVERAGE})",
                            fix="grow the GC margins in ngc_gen.data.procedural.creatures._enclosing_gc")
    return mesh, annotation, coverage


# ---- dataset --------------------------------------------------------------------------------
def shape_seed(seed: int, index: int) -> int:
    """The seed of shape `index` in the dataset of `seed` (independent streams per shape)."""
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def creature_names(n: int) -> list[str]:
    """The names of a dataset of `n` creatures."""
    return [f"creature_{i:04d}" for i in range(int(n))]


def creature_split(names: list[str], seed: int, test_fraction: float) -> dict:
    """Deterministic disjoint {train, test} split of `names` (each list sorted)."""
    if not 0.0 <= test_fraction < 1.0:
        raise DataError(f"test_fraction must lie in [0, 1), got {test_fraction}",
                        field="test_fraction", fix="use e.g. 0.25")
    n = len(names)
    n_test = int(round(n * test_fraction))
    if test_fraction > 0 and n >= 2:
        n_test = min(max(n_test, 1), n - 1)
    order = np.random.default_rng([int(seed), 7919]).permutation(n)
    test = {names[i] for i in order[:n_test]}
    return {"train": sorted(set(names) - test), "test": sorted(test)}


def _settings_key(seed: int, resolution: int) -> str:
    text = json.dumps({"version": CREATURES_VERSION, "seed": int(seed),
                       "resolution": int(resolution), "bound": BOUND, "keys": KEY_TS},
                      sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _make_timed(args):
    seed, resolution, name = args
    start = time.perf_counter()
    mesh, ann, cov = _make(seed, resolution, name, 200_000)
    return mesh, ann, cov, time.perf_counter() - start


def build_creatures(out_dir, n: int, seed: int = 0, test_fraction: float = 0.25,
                    resolution: int = 128, progress: bool | None = None,
                    workers: int | None = None, only: list[str] | None = None) -> list[dict]:
    """Build (or reuse) `n` creatures in `out_dir`: `<name>.ply` + `<name>.yaml` per shape,
    `split.json` {train, test} and `manifest.json`.

    Files are written atomically. A shape is reused when the manifest says it was built with the
    same generator version, seed and resolution and its files exist, so growing `n` only builds
    the new shapes. Returns one record per shape: name, seed, mesh, annotation (paths), split,
    vertices, faces, coverage, seconds (0 when reused). A progress bar shows when `progress` is
    True, or by default when n > 8. `only`: build and return just these names (the split still
    covers all `n`: it depends on the names alone). Missing shapes are made in `workers`
    processes (`map_shapes`)."""
    from tqdm.auto import tqdm

    if int(n) < 1:
        raise DataError(f"n must be >= 1, got {n}", field="n", fix="ask for at least one shape")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    key = _settings_key(seed, resolution)
    manifest_path = out / "manifest.json"
    manifest = {}
    if manifest_path.is_file():
        try:
            manifest = json.loads(manifest_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError):
            manifest = {}
    if manifest.get("settings") != key:
        manifest = {"settings": key, "version": CREATURES_VERSION, "seed": int(seed),
                    "resolution": int(resolution), "shapes": {}}
    names = creature_names(n)
    split = creature_split(names, seed, test_fraction)
    which = {nm: s for s in ("train", "test") for nm in split[s]}
    asked = set(names if only is None else only)
    wanted = [nm for nm in names if nm in asked]
    if len(wanted) < len(asked):
        unknown = sorted(asked - set(names))
        raise DataError(f"no creature named {', '.join(unknown)} among the {n} built",
                        fix=f"ask for creature_0000 .. creature_{int(n) - 1:04d}")
    missing = [i for i, nm in enumerate(names) if nm in asked and not (
        manifest["shapes"].get(nm) is not None and (out / f"{nm}.ply").is_file()
        and (out / f"{nm}.yaml").is_file())]
    made = map_shapes(_make_timed, [(shape_seed(seed, i), resolution, names[i]) for i in missing],
                      workers)
    bar = tqdm(total=len(missing), desc="creatures",
               disable=not (len(missing) > 8 if progress is None else progress))
    fresh = {}
    for i, (mesh, ann, cov, seconds) in zip(missing, made):
        nm = names[i]
        atomic_write(out / f"{nm}.ply", lambda f: f.write(mesh.export(file_type="ply")))
        atomic_write_text(out / f"{nm}.yaml", yaml.safe_dump(ann, sort_keys=False,
                                                              default_flow_style=None, width=100))
        fresh[nm] = round(seconds, 3)
        manifest["shapes"][nm] = {"seed": shape_seed(seed, i), "vertices": len(mesh.vertices),
                                  "faces": len(mesh.faces), "coverage": cov}
        atomic_write_text(manifest_path, json.dumps(manifest, indent=1))
        bar.update()
    bar.close()
    records = [{"name": nm, "mesh": str(out / f"{nm}.ply"), "annotation": str(out / f"{nm}.yaml"),
                "split": which[nm], **manifest["shapes"][nm], "seconds": fresh.get(nm, 0.0)}
               for nm in wanted]
    atomic_write_text(out / "split.json", json.dumps(split, indent=1))
    return records
