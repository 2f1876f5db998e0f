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
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import trimesh
import yaml

from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError
from ngc_gen.data.procedural.implicit import (block_points, grid_axes, mesh_from_field, profile_envelope,
                                   profile_norm)
from ngc_gen.data.annotations import rounded_gc_dict, similar_gc_dict
from ngc_gen.data.mesh.io import normalize
from ngc_gen.data.workers import map_shapes
from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis, smooth_min

#: Bump when the generator changes: built datasets with another version are rebuilt.
CREATURES_VERSION = 1
BOUND = 0.8
#: Normalised arc lengths of the annotation key frames, the same for every GC and shape.
KEY_TS = (0.0, 0.25, 0.5, 0.75, 1.0)
MIN_COVERAGE = 0.999
#: Coarser grids can lose thin parts (ears, tail tips): measured, 48 split one creature in two.
MIN_RESOLUTION = 64


@dataclass(frozen=True)
class PartTemplate:
    """One GC of the shared template: its name, Bezier degree, frame `up` and the part it grows
    from. Degree and up are fixed per part so every shape has the same parameter layout
    (control points x keys x caps), which the generative shape decoder needs."""

    name: str
    degree: int
    up: tuple[float, float, float]
    parent: str | None


#: The shared template, in the order GCs appear in every annotation (and the smooth-union order).
CREATURE_TEMPLATE: tuple[PartTemplate, ...] = (
    PartTemplate("torso", 3, (0.0, 0.0, 1.0), None),
    PartTemplate("neck", 2, (0.0, 1.0, 0.0), "torso"),
    PartTemplate("head", 2, (0.0, 0.0, 1.0), "neck"),
    PartTemplate("tail", 3, (0.0, 1.0, 0.0), "torso"),
    PartTemplate("leg_fl", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_fr", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_bl", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("leg_br", 2, (1.0, 0.0, 0.0), "torso"),
    PartTemplate("ear_l", 2, (1.0, 0.0, 0.0), "head"),
    PartTemplate("ear_r", 2, (1.0, 0.0, 0.0), "head"),
)
CREATURE_PARTS: tuple[str, ...] = tuple(p.name for p in CREATURE_TEMPLATE)


@dataclass
class Part:
    """One part's implicit solid in the design frame.

    Skeleton: Bezier `points`; radii (r_y, r_z) along the GC frame go from `r0` to `r1` with a
    smoothstep, times a Gaussian bump (`bump` = amplitude, centre t, width); half-ellipsoid ends of
    lengths `caps`; cross-section a lobed superellipse (`exponent`, `lobes`, `lobe_amp`,
    `phase`), turned by a twist lerped from `twist[0]` to `twist[1]` degrees. `blend` is the
    smooth-union radius with which it joins the parts before it.
    """

    name: str
    points: np.ndarray
    up: tuple[float, float, float]
    r0: tuple[float, float]
    r1: tuple[float, float]
    bump: tuple[float, float, float]
    caps: tuple[float, float]
    exponent: float
    lobes: int = 0
    lobe_amp: float = 0.0
    phase: float = 0.0
    twist: tuple[float, float] = (0.0, 0.0)
    blend: float = 0.0

    def radii(self, t: np.ndarray) -> np.ndarray:
        """(N,) normalised arc length -> (N, 2) profile radii (smooth in t)."""
        t = np.asarray(t, np.float64)
        s = (t * t * (3.0 - 2.0 * t))[:, None]
        amp, tc, w = self.bump
        bump = 1.0 + amp * np.exp(-(((t - tc) / w) ** 2))[:, None]
        return (np.asarray(self.r0) * (1.0 - s) + np.asarray(self.r1) * s) * bump

    @property
    def envelope(self) -> float:
        return profile_envelope(self.exponent, self.lobe_amp)

    def mirrored(self, name: str) -> "Part":
        """The mirror image across the y = 0 plane (lobes mirror too)."""
        pts = self.points * np.array([1.0, -1.0, 1.0])
        return Part(name, pts, self.up, self.r0, self.r1, self.bump, self.caps, self.exponent,
                    self.lobes, self.lobe_amp, -self.phase, (-self.twist[0], -self.twist[1]),
                    self.blend)


# ---- random parts ---------------------------------------------------------------------------
def _bezier(p0, p_end, degree: int, offsets) -> np.ndarray:
    """Control points of a Bezier of `degree` from p0 to p_end: the straight line's evenly
    spaced points with the inner ones moved by `offsets` ((degree - 1, 3))."""
    p0, p_end = np.asarray(p0, np.float64), np.asarray(p_end, np.float64)
    s = np.linspace(0.0, 1.0, degree + 1)[:, None]
    pts = p0 * (1.0 - s) + p_end * s
    pts[1:-1] += np.asarray(offsets, np.float64).reshape(degree - 1, 3)
    return pts


def sample_parts(seed: int) -> list[Part]:
    """Random creature parts in the design frame (about 1.2-1.8 long), in template order.

    Proportions (body, legs, neck, head, ears, tail), skeleton curvature (arched back, bent
    neck, knees, curled tail, swept ears), radius profiles (chest/hip, paws, cranium, bushy tail
    tip) and cross-sections (superellipse exponent 2.5-4, lobes on legs/tail/torso) all vary."""
    rng = np.random.default_rng(seed)
    U = rng.uniform
    deg = {p.name: p.degree for p in CREATURE_TEMPLATE}
    up = {p.name: p.up for p in CREATURE_TEMPLATE}

    # torso along x; frame y = vertical, frame z = lateral
    L = U(0.55, 0.85)
    r_vert = U(0.12, 0.18)
    r_lat = r_vert * U(0.9, 1.3)
    H = U(0.28, 0.55)  # leg length
    zc = H + 0.3 * r_vert
    arch, rise = U(-0.03, 0.06), U(-0.02, 0.06)
    torso_pts = _bezier([-L / 2, 0, zc - rise / 2], [L / 2, 0, zc + rise / 2], deg["torso"],
                        [[U(-0.03, 0.03), 0, arch + U(-0.02, 0.02)] for _ in range(2)])
    hip, chest = U(0.8, 1.05), U(0.95, 1.2)
    torso = Part("torso", torso_pts, up["torso"], (r_vert * hip, r_lat * hip),
                 (r_vert * chest, r_lat * chest), (U(0.0, 0.12), U(0.35, 0.65), U(0.2, 0.35)),
                 (U(0.6, 1.0) * r_vert * hip, U(0.6, 1.0) * r_vert * chest), U(2.6, 4.0),
                 lobes=int(rng.integers(5, 9)), lobe_amp=U(0.0, 0.04), phase=U(0, 2 * np.pi))

    # neck: from inside the chest up and forward; frame y = lateral
    a_n = math.radians(U(35.0, 75.0))
    d_n = np.array([math.cos(a_n), 0.0, math.sin(a_n)])
    perp_n = np.array([-math.sin(a_n), 0.0, math.cos(a_n)])
    n0 = np.array([L / 2 - 0.35 * r_vert, 0.0, zc + rise / 2 + 0.3 * r_vert])
    n1 = n0 + U(0.2, 0.45) * d_n
    r_neck = U(0.055, 0.09)
    neck = Part("neck", _bezier(n0, n1, deg["neck"], [U(-0.05, 0.05) * perp_n]), up["neck"],
                (r_neck, r_neck * U(0.85, 1.15)), (r_neck * U(0.65, 0.9), r_neck * U(0.65, 0.9)),
                (U(0.0, 0.15), U(0.4, 0.7), 0.25), (0.5 * r_neck, 0.5 * r_neck), U(2.5, 3.5),
                blend=U(0.05, 0.08))

    # head: from behind the neck's end toward the snout; frame y = vertical
    Rh = U(0.09, 0.14)
    Lh = U(0.12, 0.26)
    pitch = math.radians(U(-20.0, 10.0))
    d_h = np.array([math.cos(pitch), 0.0, math.sin(pitch)])
    perp_h = np.array([-math.sin(pitch), 0.0, math.cos(pitch)])
    h0 = n1 - 0.1 * Lh * d_h + 0.35 * Rh * perp_h
    h1 = h0 + Lh * d_h
    head_r0 = (Rh * U(0.85, 1.1), Rh * U(0.9, 1.15))
    snout = U(0.4, 0.75)
    head_r1 = (head_r0[0] * snout, head_r0[1] * snout)
    head = Part("head", _bezier(h0, h1, deg["head"], [U(-0.03, 0.02) * perp_h]), up["head"],
                head_r0, head_r1, (U(0.05, 0.2), U(0.15, 0.35), 0.25),
                (U(0.7, 1.0) * Rh, U(0.5, 1.0) * snout * Rh), U(2.3, 3.2),
                blend=U(0.03, 0.06))

    # tail: from inside the rump backward and up, curled, twisted lobes, bushy tip
    a_t = math.radians(U(-30.0, 60.0))
    d_t = np.array([-math.cos(a_t), 0.0, math.sin(a_t)])
    perp_t = np.array([math.sin(a_t), 0.0, math.cos(a_t)])
    t0 = np.array([-L / 2 + 0.3 * r_vert, 0.0, zc - rise / 2 + 0.2 * r_vert])
    Lt = U(0.2, 0.5)
    r_tail = U(0.03, 0.055)
    r_tip = max(r_tail * U(0.35, 0.7), 0.02)
    tail = Part("tail", _bezier(t0, t0 + Lt * d_t, deg["tail"],
                                [U(-0.08, 0.08) * perp_t for _ in range(2)]), up["tail"],
                (r_tail, r_tail), (r_tip, r_tip), (U(0.0, 0.8), U(0.75, 0.92), 0.12),
                (0.5 * r_tail, U(0.8, 1.8) * r_tip), U(2.5, 3.5),
                lobes=int(rng.integers(3, 7)), lobe_amp=U(0.05, 0.15), phase=U(0, 2 * np.pi),
                twist=(0.0, U(-180.0, 180.0)), blend=U(0.03, 0.06))

    # legs: from inside the torso straight down, splayed outward (T-pose-like), knees, paws;
    # frame y = forward, frame z = lateral. Right legs mirror the left ones.
    legs = {}
    # (name, hip x, knee range along x): front knees forward, hind hocks back
    for name, x, knee in (("leg_fl", L * (0.5 - U(0.12, 0.2)), (-0.02, 0.06)),
                          ("leg_bl", -L * (0.5 - U(0.12, 0.22)), (-0.07, 0.02))):
        y = U(0.55, 0.8) * r_lat
        r_leg = U(0.045, 0.075)
        r_end = r_leg * U(0.6, 0.9)
        paw = U(0.15, 0.5)
        foot = r_end * (1 + paw) * U(0.6, 0.9)
        p0 = [x, y, zc]
        p1 = [x + U(-0.03, 0.03), y + U(0.04, 0.16), foot]
        legs[name] = Part(name, _bezier(p0, p1, deg[name], [[U(*knee), U(0.0, 0.03), 0.0]]),
                          up[name], (r_leg, r_leg * U(0.9, 1.15)), (r_end, r_end),
                          (paw, U(0.9, 1.0), 0.12), (0.5 * r_leg, foot), U(2.5, 3.5),
                          lobes=int(rng.integers(4, 7)), lobe_amp=U(0.0, 0.1),
                          phase=U(0, 2 * np.pi), blend=U(0.04, 0.07))
    legs["leg_fr"] = legs["leg_fl"].mirrored("leg_fr")
    legs["leg_br"] = legs["leg_bl"].mirrored("leg_br")

    # ears: from inside the skull up and outward, flat (frame y = thickness ~ x), tapered
    Le = U(0.08, 0.3)
    e0 = h0 + U(0.1, 0.35) * Lh * d_h + np.array([0.0, U(0.3, 0.6) * Rh, 0.55 * Rh])
    d_e = np.array([-U(0.0, 0.4), U(0.15, 0.8), 1.0])
    d_e /= np.linalg.norm(d_e)
    width = max(U(0.3, 0.55) * Le, 0.04)
    thick = U(0.022, 0.03)
    ear = Part("ear_l", _bezier(e0, e0 + Le * d_e, deg["ear_l"],
                                [[U(-0.04, 0.02), U(-0.02, 0.03), 0.0]]), up["ear_l"],
               (thick, width), (thick * U(0.7, 0.9), max(width * U(0.3, 0.7), 0.025)),
               (U(0.0, 0.3), U(0.3, 0.6), 0.25), (0.5 * width, U(0.5, 1.2) * width * 0.5),
               U(2.5, 3.5), blend=U(0.015, 0.03))

    parts = {"torso": torso, "neck": neck, "head": head, "tail": tail, **legs,
             "ear_l": ear, "ear_r": ear.mirrored("ear_r")}
    return [parts[n] for n in CREATURE_PARTS]


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
