"""A tiny 0 A.D.-style quadruped written by the tests themselves: PMD, PSA and skeleton XML
bytes (no downloaded package).

y up, facing -z (head at negative z), 15 bones; every bone gets a small cube of 8 vertices
skinned wholly to it (so each bone carries skin), feet cubes touch y = 0. Bone order is the
skeleton XML's depth-first order, as in 0 A.D.
"""
from __future__ import annotations

import numpy as np

# name, parent, model-space position: the +x legs are named r_, as 0 A.D. does for an animal
# facing -z (its left is -x)
BONES = [
    ("root", -1, (0.0, 2.0, 1.0)),     # 0 hips: the back legs and the tail leave here
    ("spine", 0, (0.0, 2.0, 0.0)),     # 1
    ("chest", 1, (0.0, 2.0, -1.0)),    # 2 the front legs leave here
    ("neck", 2, (0.0, 2.6, -1.6)),     # 3
    ("head", 3, (0.0, 3.0, -2.2)),     # 4
    ("r_arm", 2, (0.5, 1.7, -1.0)),    # 5
    ("r_hand", 5, (0.5, 0.9, -1.0)),   # 6
    ("r_hoof", 6, (0.5, 0.15, -1.0)),  # 7
    ("l_arm", 2, (-0.5, 1.7, -1.0)),   # 8
    ("l_hand", 8, (-0.5, 0.9, -1.0)),  # 9
    ("l_hoof", 9, (-0.5, 0.15, -1.0)),  # 10
    ("r_leg", 0, (0.5, 1.7, 1.0)),     # 11
    ("r_foot", 11, (0.5, 0.15, 1.0)),  # 12
    ("l_leg", 0, (-0.5, 1.7, 1.0)),    # 13
    ("l_foot", 13, (-0.5, 0.15, 1.0)),  # 14
    ("tail", 0, (0.0, 2.1, 1.5)),      # 15
    ("tail_tip", 15, (0.0, 1.6, 1.9)),  # 16
]
NAMES = [b[0] for b in BONES]
PARENT = np.array([b[1] for b in BONES])
POS = np.array([b[2] for b in BONES], np.float64)
CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
CUBE_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
#: the structural map's expected chains (the animal's left is -x: l_ bones)
EXPECTED = {"leg_fl": ["l_arm", "l_hand", "l_hoof"], "leg_fr": ["r_arm", "r_hand", "r_hoof"],
            "leg_bl": ["l_leg", "l_foot"], "leg_br": ["r_leg", "r_foot"],
            "neck": ["neck", "head"], "head": ["head"], "tail": ["tail", "tail_tip"]}


def skeleton_xml(names=NAMES, parent=PARENT, sid: str = "Tiny") -> bytes:
    """A skeleton file with one standard skeleton (the tree of `parent`)."""
    kids: dict[int, list[int]] = {}
    for i, p in enumerate(parent):
        kids.setdefault(int(p), []).append(i)

    def bone(i, depth):
        pad = "  " * depth
        inner = "".join(bone(k, depth + 1) for k in kids.get(i, []))
        return f'{pad}<bone name="{names[i]}">\n{inner}{pad}</bone>\n' if inner else \
            f'{pad}<bone name="{names[i]}"/>\n'

    body = "".join(bone(r, 2) for r in kids[-1])
    return (f'<skeletons>\n  <standard_skeleton title="{sid}" id="{sid}">\n{body}'
            f'  </standard_skeleton>\n</skeletons>\n').encode()


def mesh_arrays(pos=POS, size: float = 0.15):
    """(vertices (8n, 3), faces (12n, 3), bone of each vertex (8n,)): a cube per bone, and two
    more along the head's snout (the head carries more skin than the tail); a cube whose bone
    is near the ground sits on it."""
    head = NAMES.index("head")
    snout = pos[head] + (pos[head] - pos[NAMES.index("neck")]) * np.array([[0.4], [0.8]])
    centre = np.vstack([pos, snout])
    bone = np.r_[np.arange(len(pos)), head, head]
    low = centre[:, 1] < 0.5
    centre[low, 1] = size  # feet cubes from y = 0
    V = (centre[:, None, :] + size * CUBE[None]).reshape(-1, 3)
    F = (CUBE_FACES[None] + 8 * np.arange(len(centre))[:, None, None]).reshape(-1, 3)
    return V, F, np.repeat(bone, 8)


def pmd_bytes(pos=POS, rot=None, version: int = 4) -> bytes:
    """A PMD of the cube mesh, each vertex wholly on its bone, bones at `pos` (B, 3) with
    rotations `rot` (B, 4) x y z w (default identity); its triangles clockwise seen from
    outside, as the game's files store them."""
    V, F, bone = mesh_arrays(pos)
    nt = 1
    vert = np.zeros(len(V), np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", (nt, 2)),
                                      ("b", "u1", 4), ("w", "<f4", 4)]))
    vert["p"] = V
    vert["n"] = [0.0, 1.0, 0.0]
    vert["b"] = 0xFF
    vert["b"][:, 0] = bone
    vert["w"][:, 0] = 1.0
    bones = np.zeros(len(pos), np.dtype([("t", "<f4", 3), ("q", "<f4", 4)]))
    bones["t"] = pos
    bones["q"] = [0.0, 0.0, 0.0, 1.0] if rot is None else rot
    body = b"".join([np.uint32(len(V)).tobytes(), np.uint32(nt).tobytes() if version >= 4 else b"",
                     vert.tobytes(), np.uint32(len(F)).tobytes(), F[:, ::-1].astype("<u2").tobytes(),
                     np.uint32(len(pos)).tobytes(), bones.tobytes(), np.uint32(0).tobytes()])
    return b"PSMD" + np.uint32(version).tobytes() + np.uint32(len(body)).tobytes() + body


def psa_bytes(t: np.ndarray, q: np.ndarray, name: str = "clip", frame_ms: float = 100.0) -> bytes:
    """A PSA of K frames: model-space translations t (K, B, 3), quaternions q (K, B, 4)."""
    K, B = t.shape[:2]
    keys = np.zeros((K, B), np.dtype([("t", "<f4", 3), ("q", "<f4", 4)]))
    keys["t"], keys["q"] = t, q
    raw = name.encode()
    body = b"".join([np.uint32(len(raw)).tobytes(), raw, np.float32(frame_ms).tobytes(),
                     np.uint32(B).tobytes(), np.uint32(K).tobytes(), keys.tobytes()])
    return b"PSSA" + np.uint32(1).tobytes() + np.uint32(len(body)).tobytes() + body


def quat_y(deg: float) -> np.ndarray:
    """The quaternion x y z w of a turn by `deg` degrees about +y."""
    a = np.radians(deg) / 2
    return np.array([0.0, np.sin(a), 0.0, np.cos(a)])
