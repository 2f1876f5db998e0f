"""Shapes as rigged, animated glTF 2.0 assets: GC chains as a skeleton, skin weights from the
NGC field, clips (edit programs, rigged collections' clips carried by GC names), and corrective
morph targets that put skinning on NGC's exact posed surface (docs/export.md)."""
from .asset import ExportSettings, Rigged, content, export_shape, rig_shape
from .clips import Clip, ClipError, program_clip, rig_clip
from .glb_writer import GLBContent, write_glb
from .playback import Playback
from .joint_chains import Skeleton, SkeletonError, build_skeleton, joint_matrices

__all__ = ["ExportSettings", "Rigged", "content", "export_shape", "rig_shape", "Clip", "ClipError",
           "program_clip", "rig_clip", "GLBContent", "write_glb", "Playback", "Skeleton",
           "SkeletonError", "build_skeleton", "joint_matrices"]
