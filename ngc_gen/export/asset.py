"""A shape as a rigged asset: mesh, skeleton, skin, optional clip and corrective shapes, in
one `GLBContent` (`ngc_gen.export.glb_writer` writes it). Settings are conf/export/default.yaml's."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .clips import Clip
from .correctives import corrective_offsets
from .glb_writer import GLBContent
from .joint_chains import Skeleton, build_skeleton, joint_matrices
from .weights import skin_weights


@dataclass(frozen=True)
class ExportSettings:
    """joints_per_gc: joints along each GC; resolution: the mesh grid; blend, falloff: the skin
    weights' widths (`weights.skin_weights`); correctives: store the morph targets; newton_steps,
    fd_step, max_step, tolerance: their projection (`correctives.corrective_offsets`);
    fold_rounds, fold_stretch, fold_off: the fins of folds smoothed away (`correctives.unfold`);
    colors: COLOR_0 by GC;
    max_key_degrees: in-between joint keys beyond this turn (`glb_writer.in_between_keys`). No
    defaults here: conf/mode/export.yaml's `export:` block is their one source."""

    joints_per_gc: int
    resolution: int
    blend: float
    falloff: float
    correctives: bool
    newton_steps: int
    fd_step: float
    max_step: float
    tolerance: float
    fold_rounds: int
    fold_stretch: float
    fold_off: float
    colors: bool
    max_key_degrees: float

    @classmethod
    def from_config(cls, d) -> "ExportSettings":
        names = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in dict(d or {}).items() if k in names})

    @classmethod
    def from_yaml(cls, **overrides) -> "ExportSettings":
        """conf/mode/export.yaml's values, some replaced (for callers without a config)."""
        from ngc_gen.conf.defaults import yaml_settings

        return yaml_settings(cls, "mode/export.yaml", "export", **overrides)


@dataclass
class Rigged:
    """A meshed shape with its skeleton and skin, before any clip."""

    shape: object
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    skeleton: Skeleton
    rest: np.ndarray
    joints: np.ndarray
    weights: np.ndarray


def _palette(n: int) -> np.ndarray:
    import colorsys

    return np.array([(*colorsys.hsv_to_rgb((0.61803 * i) % 1.0, 0.55, 0.9), 1.0)
                     for i in range(n)])


def rig_shape(shape, settings: ExportSettings, parents: dict | None = None,
              mesh=None) -> Rigged:
    """Mesh `shape` (or take `mesh`, a trimesh of it), build its skeleton and skin weights."""
    if mesh is None:
        mesh = shape.mesh(settings.resolution).mesh
    V = np.asarray(mesh.vertices, np.float64)
    F = np.asarray(mesh.faces, np.int64)
    if len(F) == 0:
        raise ValueError(f"shape {shape.name!r} meshes to nothing at resolution "
                         f"{settings.resolution}: its field has no zero level set")
    skeleton = build_skeleton(shape.gcs, settings.joints_per_gc, parents)
    rest = joint_matrices(skeleton, shape.gcs)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    J, W = skin_weights(shape, skeleton, V, settings.blend * diag, settings.falloff)
    return Rigged(shape, V, F, np.asarray(mesh.vertex_normals, np.float64), skeleton, rest, J, W)


def export_shape(shape, path, settings: ExportSettings, parents: dict | None = None,
                 make_clip=None, mesh=None) -> tuple[dict, Rigged, Clip | None]:
    """Rig `shape` (`rig_shape`), add the clip `make_clip(rigged)` gives (None: the rest pose
    only) and write the GLB to `path`: (summary, rigged, clip). sample.py mode=export, the
    editor's export button and bench/export.py all export through this."""
    from .glb_writer import write_glb

    t0 = time.perf_counter()
    rigged = rig_shape(shape, settings, parents, mesh)
    clip = make_clip(rigged) if make_clip is not None else None
    c, stats = content(rigged, clip, settings)
    n_bytes = write_glb(path, c)
    summary = {"file": str(path), "shape": shape.name, "joints": rigged.skeleton.n_joints,
               "vertices": len(rigged.vertices),
               "max_influences": int((rigged.weights > 0).sum(1).max()), "bytes": n_bytes,
               "keyframes": 0 if clip is None else len(clip.times),
               "correctives": bool(settings.correctives and clip is not None),
               "export_s": time.perf_counter() - t0, **stats}
    return summary, rigged, clip


def content(r: Rigged, clip: Clip | None, settings: ExportSettings) -> tuple[GLBContent, dict]:
    """The file's content and what it took (seconds of the correctives, their mean shift)."""
    c = GLBContent(r.vertices, r.faces, r.normals, r.skeleton.names, r.skeleton.parent, r.rest,
                   r.joints, r.weights, name=r.shape.name,
                   max_key_degrees=settings.max_key_degrees)
    if settings.colors:
        dominant = r.joints[np.arange(len(r.joints)), r.weights.argmax(1)]
        c.colors = _palette(len(r.skeleton.gc_names))[r.skeleton.gc[dominant]]
    stats = {"corrective_s": 0.0}
    if clip is None:
        return c, stats
    c.clip_name, c.times, c.world = clip.name, clip.times, clip.world
    if settings.correctives:
        t0 = time.perf_counter()
        inv = np.linalg.inv(r.rest)
        offsets = []
        fold = {"rounds": settings.fold_rounds, "stretch": settings.fold_stretch,
                "off": settings.fold_off}
        for k, posed in enumerate(clip.shapes):  # keyframes
            d, _ = corrective_offsets(r.vertices, r.normals, r.faces, r.joints, r.weights,
                                      clip.world[k] @ inv, lambda p, s=posed: s.sdf(p).numpy(),
                                      settings.newton_steps, settings.fd_step, settings.max_step,
                                      settings.tolerance, fold)
            offsets.append(d)
        c.morph = np.stack(offsets)
        c.morph_weights = np.eye(len(offsets))
        c.morph_names = [f"{clip.name}_{k:03d}" for k in range(len(offsets))]
        stats["corrective_s"] = time.perf_counter() - t0
    return c, stats
