"""Play an exported GLB back by the glTF 2.0 rules: the file's own joints, skin, clip and morph
targets, nothing of the exporter's memory. v'(t) = sum_j w_j M_j(t) B_j^-1 (v + sum_k m_k(t)
d_k). Tests, the bench and the README's animation judge the file through this, and Blender's
evaluated mesh is compared against it."""
from __future__ import annotations

import os

import numpy as np

from ngc_gen.data.rigs.gltf import _Reader, load_gltf_rig
from ngc_gen.data.rigs.gltf_json import read_gltf
from ngc_gen.data.rigs.rig import skin_vertices


class Playback:
    """The skinned mesh of a GLB at any time of its (first) clip."""

    def __init__(self, path: str | os.PathLike):
        self.rig = load_gltf_rig(path)
        g = read_gltf(path)
        reader = _Reader(g, os.fspath(path))
        self.clip = next(iter(self.rig.clips), None)
        mesh_node = next(i for i, n in enumerate(g.nodes) if n.mesh is not None)
        prim = g.meshes[g.nodes[mesh_node].mesh].primitives[0]
        self.targets = np.stack([reader.accessor(t["POSITION"], "morph target")
                                 for t in (prim.targets or [])]) if prim.targets else None
        self.weight_times = self.weight_values = None
        self.keyframe_times = None
        for anim in g.animations or []:
            if isinstance(anim.extras, dict) and "keyframes" in anim.extras:
                self.keyframe_times = np.asarray(anim.extras["keyframes"], np.float64)
            for ch in anim.channels:
                if ch.target.node == mesh_node and ch.target.path == "weights":
                    s = anim.samplers[ch.sampler]
                    self.weight_times = reader.accessor(s.input, "times").ravel()
                    n = len(self.targets)
                    self.weight_values = reader.accessor(s.output, "weights").reshape(-1, n)
            break
        self.joint_names = self.rig.joint_names
        self.faces = self.rig.faces

    @property
    def times(self) -> np.ndarray:
        """The clip's key times (the rest pose alone: [0])."""
        if self.clip is None:
            return np.zeros(1)
        return np.unique(np.concatenate([c.times for c in self.rig.clips[self.clip].channels]))

    @property
    def keyframes(self) -> np.ndarray:
        """The exporter's keyframes (the poses its corrective shapes are exact at: the
        animation's `extras.keyframes`); a file without them: its key times."""
        return self.times if self.keyframe_times is None else self.keyframe_times

    def morph_weights(self, time: float) -> np.ndarray | None:
        if self.targets is None or self.weight_times is None:
            return None
        t, v = self.weight_times, self.weight_values
        return np.stack([np.interp(time, t, v[:, k]) for k in range(v.shape[1])])

    def vertices(self, time: float | None = None, morph: bool = True) -> np.ndarray:
        """(V, 3) the mesh at `time` of the clip (None: the bind pose); morph=False: skinning
        alone."""
        base = self.rig.vertices
        if time is None:
            return base.copy()
        w = self.morph_weights(time) if morph else None
        if w is not None:
            base = base + np.einsum("k,kvc->vc", w, self.targets)
        return skin_vertices(base, self.rig.skin_joints, self.rig.skin_weights,
                             self.rig.skin_matrices(self.clip, float(time)))

    def joint_positions(self, time: float | None = None) -> np.ndarray:
        return self.rig.joint_positions(None if time is None else self.clip,
                                        0.0 if time is None else float(time))
