"""A glTF 2.0 / GLB file's JSON and binary chunk, read with the standard library's json.

pygltflib's reader builds every object through dataclasses_json, which takes seconds for a
rigged animal (2,000 accessors: ~20 s under load against 0.1 s for json.loads); the rig reader
needs only attribute access to the JSON. `GLTFData` gives that with pygltflib's names (the
JSON keys: `g.accessors[i].componentType`); a key the file lacks reads None, `extras` stays the
plain mapping."""
from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

GLB_MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


class GLTFObject:
    """One JSON object: its keys as attributes (None where absent), `obj[key]` too."""

    def __init__(self, d: dict):
        self.__dict__.update({k: _wrap(v, k) for k, v in d.items()})

    def __getattr__(self, key):  # only reached for keys the object lacks
        if key.startswith("__"):
            raise AttributeError(key)
        return None

    def __getitem__(self, key):
        return self.__dict__[key]

    def get(self, key, default=None):
        return self.__dict__.get(key, default)


def _wrap(x, key: str | None = None):
    if key == "extras":
        return x
    if isinstance(x, dict):
        return GLTFObject(x)
    if isinstance(x, list):
        return [_wrap(v) for v in x]
    return x


class GLTFData(GLTFObject):
    """A whole file: top-level lists (nodes, meshes, accessors, ...; [] where absent), the GLB's
    binary chunk (`binary_blob()`) and data: URIs (`get_data_from_buffer_uri`)."""

    LISTS = ("nodes", "meshes", "skins", "accessors", "bufferViews", "buffers", "animations",
             "scenes", "materials")

    def __init__(self, d: dict, blob: bytes | None):
        super().__init__(d)
        for key in self.LISTS:
            if self.__dict__.get(key) is None:
                self.__dict__[key] = []
        self._blob = blob

    def binary_blob(self) -> bytes | None:
        return self._blob

    @staticmethod
    def get_data_from_buffer_uri(uri: str) -> bytes:
        if not uri.startswith("data:"):
            raise ValueError(f"not a data URI: {uri[:40]!r}")
        return base64.b64decode(uri.split(",", 1)[1])


def read_gltf(path) -> GLTFData:
    """A .glb (header, JSON chunk, optional BIN chunk) or .gltf (JSON) file; ValueError on a
    malformed container."""
    data = Path(path).read_bytes()
    if len(data) >= 12 and struct.unpack_from("<I", data, 0)[0] == GLB_MAGIC:
        _, version, length = struct.unpack_from("<III", data, 0)
        if version != 2 or length > len(data):
            raise ValueError(f"GLB version {version}, {length} bytes declared, "
                             f"{len(data)} in the file")
        chunks, at = {}, 12
        while at + 8 <= length:
            size, kind = struct.unpack_from("<II", data, at)
            if at + 8 + size > length:
                raise ValueError("a GLB chunk runs past the end of the file")
            chunks.setdefault(kind, data[at + 8:at + 8 + size])
            at += 8 + size
        if JSON_CHUNK not in chunks:
            raise ValueError("no JSON chunk")
        d = json.loads(chunks[JSON_CHUNK].decode("utf-8"))
        return GLTFData(d, chunks.get(BIN_CHUNK))
    return GLTFData(json.loads(data.decode("utf-8")), None)
