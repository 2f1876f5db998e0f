"""Test meshes for template transfer: a stick quadruped (torso, four legs, neck, head, tail;
y up, facing +z like the animals), a box-and-sticks chair, a torus and a sphere."""
from __future__ import annotations

import numpy as np
import trimesh


def tubes(segments, radii, h=0.025) -> trimesh.Trimesh:
    """A watertight union of round tubes around segments [(a, b)] with one radius each."""
    from skimage.measure import marching_cubes

    seg = np.asarray(segments, dtype=float)
    r = np.asarray(radii, dtype=float)
    lo, hi = seg.reshape(-1, 3).min(0) - r.max() - 3 * h, seg.reshape(-1, 3).max(0) + r.max() + 3 * h
    axes = [np.arange(a, b + h, h) for a, b in zip(lo, hi)]
    P = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    d = np.full(len(P), np.inf)
    for (a, b), rr in zip(seg, r):
        t = np.clip((P - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        d = np.minimum(d, np.linalg.norm(P - (a + t[:, None] * (b - a)), axis=1) - rr)
    v, f, _, _ = marching_cubes(d.reshape([len(x) for x in axes]), 0.0, spacing=(h, h, h))
    return trimesh.Trimesh(v + lo, f, process=True)


def quadruped(length=0.8, leg=0.75, neck=0.45, tail=0.4, rotation=None, grazing=False,
              tail_radius=0.035, tail_dir=(0.7, 0.7), neck_radius=0.07, head=(0.25, 0.09)):
    """(mesh, points): a stick quadruped and named points on it (front-left foot, head tip,
    tail tip, torso middle, tail root: a fifth of the way out), y up, facing +z (or turned by `rotation` (3, 3):
    world' = R world); tail=0: no tail; grazing: the neck lowered forward and the head down to
    the ground (far from where a template's head sits); tail_dir: the tail's (down, back) per
    unit of `tail` ((0, 1): straight back); tail_radius: one radius or several, root to tip (a
    tail tapering in as many pieces); head: its (length, radius)."""
    z0, z1, y = -length / 2, length / 2, 0.1
    feet = {"fl": (0.14, y - leg, z1 - 0.05), "fr": (-0.14, y - leg, z1 - 0.05),
            "bl": (0.14, y - leg, z0 + 0.05), "br": (-0.14, y - leg, z0 + 0.05)}
    hips = {k: (f[0], y, f[2]) for k, f in feet.items()}
    if grazing:
        neck_top = (0.0, y - neck * 1.15, z1 + neck * 0.15)
        head_tip = (0.0, neck_top[1] - 0.22, neck_top[2] + 0.1)
    else:
        neck_top = (0.0, y + neck * 0.8, z1 + neck * 0.5)
        head_tip = (0.0, neck_top[1] - 0.05, neck_top[2] + head[0])
    tail_tip = (0.0, y - tail * tail_dir[0], z0 - tail * tail_dir[1])
    taper = np.atleast_1d(np.asarray(tail_radius, dtype=float))
    knots = np.linspace((0, y, z0), tail_tip, len(taper) + 1)
    segs = [((0, y, z0), (0, y, z1))] + [(hips[k], feet[k]) for k in feet] + [
        ((0, y, z1), neck_top), (neck_top, head_tip)] + list(zip(knots[:-1], knots[1:]))
    radii = [0.16, 0.06, 0.06, 0.06, 0.06, neck_radius, head[1], *taper]
    if not tail:
        segs, radii = segs[:-len(taper)], radii[:-len(taper)]
    mesh = tubes(segs, radii)
    points = {"foot_fl": feet["fl"], "head_tip": head_tip, "tail_tip": tail_tip,
              "torso": (0.0, y, 0.0), "tail_root": knots[0] + 0.2 * (knots[-1] - knots[0])}
    points = {k: np.asarray(v, dtype=float) for k, v in points.items()}
    if rotation is not None:
        mesh = trimesh.Trimesh(mesh.vertices @ np.asarray(rotation).T, mesh.faces, process=False)
        points = {k: np.asarray(rotation) @ v for k, v in points.items()}
    return mesh, points


def chair() -> trimesh.Trimesh:
    """A box seat on four stick legs with a box back (y up)."""
    seat = trimesh.creation.box(extents=[0.8, 0.08, 0.8])
    legs = [trimesh.creation.box(extents=[0.07, 0.7, 0.07]).apply_translation([x, -0.39, z])
            for x in (-0.35, 0.35) for z in (-0.35, 0.35)]
    back = trimesh.creation.box(extents=[0.8, 0.8, 0.07]).apply_translation([0, 0.44, -0.365])
    return trimesh.util.concatenate([seat, *legs, back])


def torus() -> trimesh.Trimesh:
    return trimesh.creation.torus(major_radius=0.6, minor_radius=0.15)


def sphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=3, radius=0.6)
