"""0 A.D.'s binary model and animation files and its skeleton XML, read with numpy.

PMD (version 3 or 4, little-endian): ``"PSMD"``, u32 version, u32 data size (file length -
12); u32 numVertices; u32 numTexCoords (version >= 4; 1 before); per vertex 3 f32 position,
3 f32 normal, numTexCoords x 2 f32 UV, 4 u8 bone indices (0xFF: unused), 4 f32 weights; u32
numFaces, numFaces x 3 u16; u32 numBones, per bone 3 f32 translation + 4 f32 quaternion
(x y z w): its rest (bind) transform in model space; then u32 numPropPoints and the props.

PSA (version 1): ``"PSSA"``, u32 version, u32 data size; u32 name length + name; f32 frame
length (milliseconds); u32 numBones; u32 numFrames; numFrames x numBones x (3 f32 translation +
4 f32 quaternion), model space, in the PMD's bone order.

Skeleton XML: ``<standard_skeleton id=...>`` holds the bone tree (nested ``<bone name=...>``);
bone i of a PMD is the i-th ``<bone>`` in document (depth-first) order. Each record is parsed
by one structured numpy dtype (no loop over vertices or frames); a truncated file or one that
is not of its kind is a one-line DataError naming the file.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ngc_gen.data.errors import DataError

PMD_VERSIONS = (3, 4)
PSA_VERSIONS = (1,)
BONE = np.dtype([("t", "<f4", 3), ("q", "<f4", 4)])


@dataclass(frozen=True)
class PMD:
    """One PMD: positions, normals (V, 3); uv (V, T, 2); bones (V, 4) int (-1: unused);
    weights (V, 4); faces (F, 3) counter-clockwise seen from outside (the file stores them
    clockwise, the engine's winding: read as they are, every closed piece is inside out and its
    winding number is -1 within, and the stored normals disagree); rest translation (B, 3) and quaternion x y z w (B, 4) of
    each bone in model space; `source`: the file."""

    positions: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    bones: np.ndarray
    weights: np.ndarray
    faces: np.ndarray
    bone_translation: np.ndarray
    bone_rotation: np.ndarray
    source: str


@dataclass(frozen=True)
class PSA:
    """One PSA: its name, frame length (seconds), translation (K, B, 3) and quaternion x y z w
    (K, B, 4) of every bone at each of its K frames, in model space."""

    name: str
    frame_length: float
    translation: np.ndarray
    rotation: np.ndarray
    source: str


@dataclass(frozen=True)
class Skeleton:
    """A standard skeleton: its id, bone names and parents (index, -1: the root) in document
    order (the PMD's bone order)."""

    id: str
    names: tuple[str, ...]
    parent: np.ndarray
    source: str


class _Reader:
    """Sequential little-endian reads from bytes; a short read is a DataError naming the file."""

    def __init__(self, data: bytes, source: str, kind: str):
        self.data, self.pos, self.source, self.kind = data, 0, source, kind

    def fail(self, what: str) -> DataError:
        return DataError(f"not a valid {self.kind} file: {what}", path=self.source,
                         fix="re-export it, or remove it from the folder")

    def take(self, dtype, count: int, what: str) -> np.ndarray:
        dtype = np.dtype(dtype)
        end = self.pos + dtype.itemsize * count
        if count < 0 or end > len(self.data):
            raise self.fail(f"truncated in {what} (needs {end} bytes, has {len(self.data)})")
        out = np.frombuffer(self.data, dtype, count, self.pos)
        self.pos = end
        return out

    def u32(self, what: str) -> int:
        return int(self.take("<u4", 1, what)[0])

    def header(self, magic: bytes, versions: tuple[int, ...]) -> int:
        if self.data[:4] != magic:
            raise self.fail(f"it does not start with {magic.decode()!r}")
        self.pos = 4
        version, size = self.u32("the header"), self.u32("the header")
        if version not in versions:
            raise self.fail(f"version {version} (readable: {', '.join(map(str, versions))})")
        if size != len(self.data) - 12:
            raise self.fail(f"the header gives {size} data bytes, the file has "
                            f"{len(self.data) - 12} (truncated?)")
        return version


def _bytes(src: str | os.PathLike | bytes, name: str | None) -> tuple[bytes, str]:
    if isinstance(src, (bytes, bytearray, memoryview)):
        return bytes(src), name or "<bytes>"
    try:
        return Path(src).read_bytes(), name or os.fspath(src)
    except OSError as e:
        raise DataError(f"cannot read it ({e.strerror or e})", path=os.fspath(src)) from None


def read_pmd(src: str | os.PathLike | bytes, name: str | None = None) -> PMD:
    """A PMD file (path or bytes; `name` names it in errors) -> PMD (module docstring)."""
    data, source = _bytes(src, name)
    r = _Reader(data, source, "PMD")
    version = r.header(b"PSMD", PMD_VERSIONS)
    nv = r.u32("the vertex count")
    nt = r.u32("the UV set count") if version >= 4 else 1
    vert = np.dtype([("p", "<f4", 3), ("n", "<f4", 3), ("uv", "<f4", (nt, 2)),
                     ("b", "u1", 4), ("w", "<f4", 4)])
    v = r.take(vert, nv, "the vertices")
    faces = r.take("<u2", 3 * r.u32("the face count"), "the faces").reshape(-1, 3)
    bones = r.take(BONE, r.u32("the bone count"), "the bones")
    nb = len(bones)
    if len(faces) and int(faces.max()) >= nv:
        raise r.fail(f"a face uses vertex {int(faces.max())} of {nv}")
    b = v["b"].astype(np.int64)
    b[b == 0xFF] = -1
    if int(b.max(initial=-1)) >= nb:
        raise r.fail(f"a vertex uses bone {int(b.max())} of {nb}")
    w = np.where(b >= 0, v["w"], 0.0).astype(np.float64)
    return PMD(positions=v["p"].astype(np.float64), normals=v["n"].astype(np.float64),
               uv=v["uv"].astype(np.float64), bones=b, weights=w,
               faces=faces[:, ::-1].astype(np.int64), bone_translation=bones["t"].astype(np.float64),
               bone_rotation=bones["q"].astype(np.float64), source=source)


def read_psa(src: str | os.PathLike | bytes, name: str | None = None) -> PSA:
    """A PSA file (path or bytes) -> PSA (module docstring)."""
    data, source = _bytes(src, name)
    r = _Reader(data, source, "PSA")
    r.header(b"PSSA", PSA_VERSIONS)
    title = r.take("u1", r.u32("the name length"), "the name").tobytes()
    frame_ms = float(r.take("<f4", 1, "the frame length")[0])
    nb, nk = r.u32("the bone count"), r.u32("the frame count")
    keys = r.take(BONE, nb * nk, "the frames").reshape(nk, nb)
    if not (np.isfinite(frame_ms) and frame_ms > 0):
        raise r.fail(f"frame length {frame_ms} ms")
    if r.pos != len(data):
        raise r.fail(f"{len(data) - r.pos} bytes after the last frame")
    return PSA(name=title.decode("utf-8", "replace").rstrip("\0"), frame_length=frame_ms / 1000.0,
               translation=keys["t"].astype(np.float64), rotation=keys["q"].astype(np.float64),
               source=source)


def read_skeletons(src: str | os.PathLike | bytes, name: str | None = None) -> list[Skeleton]:
    """The standard skeletons of a skeleton XML file (path or bytes)."""
    data, source = _bytes(src, name)
    try:
        root = ET.fromstring(data)
    except ET.ParseError as e:
        raise DataError(f"not a valid skeleton XML file ({e})", path=source,
                        fix="give a 0 A.D. skeleton file (<skeletons><standard_skeleton ...>)"
                        ) from None
    out = []
    for std in root.iter("standard_skeleton"):
        names, parent = [], []

        def walk(node, p):
            for bone in node.findall("bone"):
                names.append(bone.get("name", f"bone{len(names)}"))
                parent.append(p)
                walk(bone, len(names) - 1)

        walk(std, -1)
        if names:
            out.append(Skeleton(id=std.get("id", std.get("title", f"skeleton{len(out)}")),
                                names=tuple(names), parent=np.asarray(parent, np.int64),
                                source=source))
    if not out:
        raise DataError("no <standard_skeleton> with bones in it", path=source,
                        fix="give a 0 A.D. skeleton file (<skeletons><standard_skeleton ...>)")
    return out
