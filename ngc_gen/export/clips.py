"""Clips: keyframes of a shape's skeleton, each with the posed shape NGC meshes exactly.

Two sources:
- an edit program: rest, then the shape after each of its ops (keyframes at its steps);
- a rigged collection's clip (a glTF rig and the template that maps its joint chains to GC
  names), carried onto any shape with the template's GC names: every joint of a GC turns as the
  source's chain joint at the same place along the chain turns (its world rotation change at
  that frame: the rig is in the collection's body frame), the chains hang from their parents
  with the shape's own bone lengths, and the root moves as the source's root, scaled by the
  ratio of the root GCs' lengths. A GC the source has no chain for keeps its rest pose
  relative to its parent.
The posed GCs follow the joints: each curve's points are skinned by its own chain (the tents
of `weights.chain_tents`) and the curve refitted (a Bezier by least squares at the same curve
parameters, which is exact for a rigid motion), `up` turned with the chain's first joint.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ngc_gen.geometry import GeneralizedCylinder, bernstein_basis

from .joint_chains import Skeleton, joint_matrices
from .weights import chain_tents


class ClipError(ValueError):
    """A clip that cannot be carried onto a shape (no GC names in common, an empty clip)."""


@dataclass
class Clip:
    """name; times (K,) seconds; world (K, J, 4, 4) joint world matrices; shapes: K posed
    `Shape`s (the shape each keyframe's correction is measured on)."""

    name: str
    times: np.ndarray
    world: np.ndarray
    shapes: list


def program_clip(shape, skeleton: Skeleton, program, seconds_per_step: float = 1.0) -> Clip:
    """Rest, then the shape after each op of an `ngc_gen.edit.EditProgram` in turn."""
    from dataclasses import replace

    shapes = [shape] + [shape.edited(replace(program, ops=program.ops[:i + 1]))
                        for i in range(len(program.ops))]
    world = np.stack([joint_matrices(skeleton, s.gcs) for s in shapes])
    times = np.arange(len(shapes), dtype=np.float64) * float(seconds_per_step)
    return Clip(program.name, times, world, shapes)


def _rotations(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m[..., :3, :3])
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, -1] *= d[..., None]
    return u @ vt


def retarget(skeleton: Skeleton, rest: np.ndarray, src_rest: np.ndarray, src_pose: np.ndarray,
             chains: dict[str, list[int]], root_scale: float) -> np.ndarray:
    """(J, 4, 4) world matrices of `skeleton` (rest world matrices `rest` (J, 4, 4)) at one
    frame of a source rig: src_rest, src_pose (N, 4, 4) the source joints' world matrices;
    chains: GC name -> the source joint indices along it (empty or absent: none)."""
    J = skeleton.n_joints
    delta = np.tile(np.eye(3), (J, 1, 1))
    own = np.zeros(J, bool)
    Rr, Rp = _rotations(src_rest), _rotations(src_pose)
    t_mid = (skeleton.k + 0.5) / skeleton.per_gc
    for g, name in enumerate(skeleton.gc_names):  # GCs (tens)
        chain = chains.get(name) or []
        if not chain:
            continue
        m = np.flatnonzero(skeleton.gc == g)
        i = np.minimum((t_mid[m] * len(chain)).astype(np.int64), len(chain) - 1)
        c = np.asarray(chain)[i]
        delta[m] = Rp[c] @ np.swapaxes(Rr[c], 1, 2)
        own[m] = True
    out = rest.copy()
    root_gc = int(skeleton.gc[skeleton.parent < 0][0])
    root_chain = chains.get(skeleton.gc_names[root_gc]) or []
    for j in skeleton.order():  # joints (tens), never vertices
        p = skeleton.parent[j]
        if p < 0:
            shift = np.zeros(3)
            if root_chain:
                shift = (src_pose[root_chain[0], :3, 3] - src_rest[root_chain[0], :3, 3])
            out[j, :3, 3] = rest[j, :3, 3] + root_scale * shift
            continue
        if not own[j]:
            delta[j] = delta[p]
        out[j, :3, 3] = out[p, :3, 3] + delta[p] @ (rest[j, :3, 3] - rest[p, :3, 3])
        out[j, :3, :3] = delta[j] @ rest[j, :3, :3]
    root = skeleton.parent < 0
    out[root, :3, :3] = delta[root] @ rest[root, :3, :3]
    return out


def posed_gcs(skeleton: Skeleton, gcs: list[GeneralizedCylinder], rest: np.ndarray,
              world: np.ndarray, samples: int = 33) -> list[GeneralizedCylinder]:
    """The GCs moved by the skeleton from `rest` to `world` (J, 4, 4): curve points skinned by
    their own chain, the curve refitted (see the module docstring)."""
    skin = world @ np.linalg.inv(rest)  # (J, 4, 4)
    out = []
    t = np.linspace(0.0, 1.0, samples)
    for g, gc in enumerate(gcs):  # GCs (tens)
        s = gc.arc.s_of_t(gc.arc_of_t(torch.as_tensor(t))).numpy()
        P = gc.curve.evaluate(torch.as_tensor(s))[0].numpy()
        tc = 1.0 - t if skeleton.reversed[g] else t
        k, w = chain_tents(tc, skeleton.per_gc)
        M = np.einsum("vk,vkab->vab", w, skin[g * skeleton.per_gc + k])
        Q = np.einsum("vab,vb->va", M[:, :3, :3], P) + M[:, :3, 3]
        if gc.curve.kind == "bezier":
            B = bernstein_basis(gc.curve.degree, s)
            ctrl = np.linalg.lstsq(B, Q, rcond=None)[0]
        else:  # a spline through its points: move each point as the curve sample nearest it
            near = np.argmin(np.linalg.norm(gc.curve.points[:, None] - P[None], axis=-1), 1)
            Mp = M[near]
            ctrl = np.einsum("vab,vb->va", Mp[:, :3, :3], gc.curve.points) + Mp[:, :3, 3]
        first = g * skeleton.per_gc + (skeleton.per_gc - 1 if skeleton.reversed[g] else 0)
        up = _rotations(skin[first][None])[0] @ gc.up
        out.append(gc.replace(curve=gc.curve.with_points(ctrl), up=up))
    return out


def rig_clip(shape, skeleton: Skeleton, rig, clip: str, chains: dict[str, list[int]],
             frames: int, fps: float = 0.0) -> Clip:
    """`frames` keyframes of `clip` of `rig` (a `ngc_gen.data.rigs.rig.Rig`) over its duration,
    carried onto `shape` by GC names (see the module docstring). chains: GC name -> indices
    into rig.joints (the template's chains). fps > 0: keyframes that far apart in time instead
    of the clip's own timing."""
    common = [n for n in skeleton.gc_names if chains.get(n)]
    if not common:
        raise ClipError(f"the clip's rig has no joint chain for any of the shape's GCs "
                        f"{skeleton.gc_names}")
    if int(frames) < 2:
        raise ClipError(f"a clip needs at least 2 frames, got {frames}")
    c = rig.clip(clip)
    times = c.start + np.arange(int(frames)) / (int(frames) - 1) * c.duration
    rest = joint_matrices(skeleton, shape.gcs)
    src_rest = rig.world_matrices(None)[rig.joints]
    root_name = skeleton.gc_names[int(skeleton.gc[skeleton.parent < 0][0])]
    root_chain = chains.get(root_name) or []
    scale = 1.0
    if len(root_chain) >= 2:
        src_len = np.linalg.norm(np.diff(src_rest[root_chain, :3, 3], axis=0), axis=1).sum()
        scale = shape.gcs[skeleton.gc_names.index(root_name)].length / max(src_len, 1e-12)
    world, shapes = [], []
    for tm in times:  # keyframes
        w = retarget(skeleton, rest, src_rest, rig.world_matrices(clip, float(tm))[rig.joints],
                     chains, scale)
        world.append(w)
        shapes.append(shape.replaced(gcs=posed_gcs(skeleton, shape.gcs, rest, w)))
    out_times = times - times[0] if fps <= 0 else np.arange(len(times)) / float(fps)
    return Clip(f"{clip}", out_times, np.stack(world), shapes)
