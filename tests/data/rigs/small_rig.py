"""A small skinned, animated glTF written by the tests themselves (no downloaded asset).

Nodes: Armature (not a joint, translated by (0, 0, 1)) -> Root (joint) -> Child (joint, at
(0, 1, 0) from Root), and the skinned mesh node. Three vertices in bind space: v0 on Root,
v1 on Child, v2 half on each. Clip "Bend": Root translates (0,0,0) -> (2,0,0) over t in
[0, 2]; Child turns 0 -> 90 degrees about z over t in [0, 1].
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pygltflib

VERTICES = np.array([[1.0, 0.0, 1.0], [0.0, 2.0, 1.0], [0.0, 1.5, 1.0]], np.float32)
JOINTS = np.array([[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]], np.uint8)
WEIGHTS = np.array([[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0, 0]], np.float32)
Q90 = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]


def write_small_rig(path: Path, extra_joint: bool = False) -> Path:
    """Write the rig to `path` (.glb). extra_joint: a third joint 'Loose' that carries skin
    weight (v0 half on it) and that no template claims."""
    names = ["Root", "Child"] + (["Loose"] if extra_joint else [])
    weights = WEIGHTS.copy()
    joints = JOINTS.copy()
    if extra_joint:
        joints[0] = [0, 2, 0, 0]
        weights[0] = [0.5, 0.5, 0, 0]
    ibm = np.stack([np.eye(4)] * len(names)).astype(np.float32)
    ibm[0, :3, 3] = [0, 0, -1]   # bind: Root at (0, 0, 1)
    ibm[1, :3, 3] = [0, -1, -1]  # Child at (0, 1, 1)
    if extra_joint:
        ibm[2, :3, 3] = [0, 0, -1]
    arrays = [
        (VERTICES, pygltflib.FLOAT, "VEC3"),
        (np.array([0, 1, 2], np.uint16), pygltflib.UNSIGNED_SHORT, "SCALAR"),
        (joints, pygltflib.UNSIGNED_BYTE, "VEC4"),
        (weights, pygltflib.FLOAT, "VEC4"),
        (ibm.transpose(0, 2, 1).reshape(len(names), 16), pygltflib.FLOAT, "MAT4"),  # column-major
        (np.array([0.0, 2.0], np.float32), pygltflib.FLOAT, "SCALAR"),
        (np.array([[0, 0, 0], [2, 0, 0]], np.float32), pygltflib.FLOAT, "VEC3"),
        (np.array([0.0, 1.0], np.float32), pygltflib.FLOAT, "SCALAR"),
        (np.array([[0, 0, 0, 1], Q90], np.float32), pygltflib.FLOAT, "VEC4"),
    ]
    blob, views, accessors = b"", [], []
    for i, (a, ctype, kind) in enumerate(arrays):
        data = np.ascontiguousarray(a).tobytes()
        views.append(pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(data)))
        flat = a.reshape(len(a), -1)
        accessors.append(pygltflib.Accessor(
            bufferView=i, componentType=ctype, count=len(a), type=kind,
            max=flat.max(0).tolist() if i in (0, 5, 7) else None,
            min=flat.min(0).tolist() if i in (0, 5, 7) else None))
        blob += data + b"\0" * (-len(data) % 4)
    joint_nodes = [1, 2] + ([3] if extra_joint else [])
    nodes = [pygltflib.Node(name="Armature", translation=[0, 0, 1], children=[1]),
             pygltflib.Node(name="Root", children=[2] + ([3] if extra_joint else [])),
             pygltflib.Node(name="Child", translation=[0, 1, 0])]
    if extra_joint:
        nodes.append(pygltflib.Node(name="Loose"))
    nodes.append(pygltflib.Node(name="Mesh", mesh=0, skin=0))
    g = pygltflib.GLTF2(
        scene=0, scenes=[pygltflib.Scene(nodes=[0, len(nodes) - 1])], nodes=nodes,
        meshes=[pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=0, JOINTS_0=2, WEIGHTS_0=3), indices=1)])],
        skins=[pygltflib.Skin(joints=joint_nodes, inverseBindMatrices=4)],
        animations=[pygltflib.Animation(name="Bend", samplers=[
            pygltflib.AnimationSampler(input=5, output=6, interpolation="LINEAR"),
            pygltflib.AnimationSampler(input=7, output=8, interpolation="LINEAR")], channels=[
            pygltflib.AnimationChannel(sampler=0, target=pygltflib.AnimationChannelTarget(node=1, path="translation")),
            pygltflib.AnimationChannel(sampler=1, target=pygltflib.AnimationChannelTarget(node=2, path="rotation"))])],
        buffers=[pygltflib.Buffer(byteLength=len(blob))], bufferViews=views, accessors=accessors)
    g.set_binary_blob(blob)
    g.save_binary(str(path))
    return path
