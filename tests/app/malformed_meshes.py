"""Fifteen malformed mesh files of the kinds users send (broken glTF JSON, an index out of range,
a missing .bin, infinite vertices, recursive nodes, an OFF with no faces, truncated PLY, ...),
each with the words its refusal must hold. Standard library only: `bench/cli.py` times the
refusals with the same files."""
from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

TRIANGLE = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]


def _gltf(positions, indices, *, nodes=None, uri="data", index_type=5125) -> tuple[dict, bytes]:
    """A one-primitive glTF document and its buffer (positions float32, indices uint32)."""
    pos = struct.pack(f"<{3 * len(positions)}f", *[c for p in positions for c in p])
    fmt = {5125: "I", 5123: "H"}[index_type]
    idx = struct.pack(f"<{len(indices)}{fmt}", *indices)
    idx += b"\0" * (-len(idx) % 4)
    data = pos + idx
    buffer = {"byteLength": len(data)}
    if uri == "data":
        buffer["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    elif uri is not None:
        buffer["uri"] = uri
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes or [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [buffer],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
                           {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(positions),
                          "type": "VEC3"},
                         {"bufferView": 1, "componentType": index_type, "count": len(indices),
                          "type": "SCALAR"}]}
    return doc, data


def _glb(doc: dict, data: bytes, cut: int = 0) -> bytes:
    doc = {**doc, "buffers": [{"byteLength": len(data)}]}
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(data),
                                                                       0x004E4942) + data
    out = struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body
    return out[:len(out) - cut] if cut else out


def _ply_binary(vertices, faces) -> bytes:
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(vertices)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(faces)}\n"
            "property list uchar int vertex_indices\nend_header\n").encode()
    body = b"".join(struct.pack("<3f", *v) for v in vertices)
    body += b"".join(struct.pack("<B3i", 3, *f) for f in faces)
    return head + body


def _ply_ascii(vertices: list[str], faces: list[str], n_faces: int | None = None) -> str:
    return ("ply\nformat ascii 1.0\n"
            f"element vertex {len(vertices)}\nproperty float x\nproperty float y\n"
            "property float z\n"
            f"element face {len(faces) if n_faces is None else n_faces}\n"
            "property list uchar int vertex_indices\nend_header\n"
            + "".join(v + "\n" for v in vertices) + "".join(f + "\n" for f in faces))


def write_malformed(folder: Path) -> dict[str, tuple[Path, str]]:
    """{case: (file, regex its one-line refusal must match)}; each file alone in a subfolder of
    `folder` named after the case (a `data=folder` data.path)."""
    files: dict[str, tuple[str, bytes | str, str]] = {}
    doc, data = _gltf(TRIANGLE, [0, 1, 2])
    files["gltf_broken_json"] = ("mesh.gltf", json.dumps(doc)[:-40],
                                 r"glTF JSON does not parse")
    files["gltf_missing_bin"] = ("mesh.gltf", json.dumps(_gltf(TRIANGLE, [0, 1, 2],
                                                               uri="mesh.bin")[0]),
                                 r"buffer 0 file 'mesh\.bin' is missing")
    files["gltf_index_out_of_range"] = ("mesh.gltf", json.dumps(_gltf(TRIANGLE, [0, 1, 7])[0]),
                                        r"face indices span \[0, 7\] but the mesh has 3 vertices")
    files["gltf_infinite_vertices"] = (
        "mesh.gltf", json.dumps(_gltf([(0.0, 0.0, 0.0), (float("inf"), 0.0, 0.0),
                                       (0.0, 1.0, 0.0)], [0, 1, 2])[0]),
        r"1 of 3 vertices are NaN or infinite")
    files["gltf_recursive_nodes"] = (
        "mesh.gltf", json.dumps(_gltf(TRIANGLE, [0, 1, 2], nodes=[
            {"mesh": 0, "children": [1]}, {"children": [0]}])[0]),
        r"node 0 is its own descendant")
    bad_accessor = _gltf(TRIANGLE, [0, 1, 2])[0]
    bad_accessor["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 5
    files["gltf_accessor_missing"] = ("mesh.gltf", json.dumps(bad_accessor),
                                      r"attributes\.POSITION = 5 is out of range")
    short = _gltf(TRIANGLE, [0, 1, 2], uri="mesh.bin")[0]
    files["gltf_short_bin"] = ("mesh.gltf", json.dumps(short),
                               r"buffer 0 holds 20 bytes, fewer than its byteLength")
    files["glb_truncated"] = ("mesh.glb", _glb(doc, data, cut=16), r"the file ends early")
    files["glb_broken_json"] = ("mesh.glb", _glb(doc, data).replace(b'"asset"', b'"asset!', 1),
                                r"glTF JSON does not parse")
    files["off_no_faces"] = ("mesh.off", "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n",
                             r"no triangles \(its OFF header declares no faces\)")
    files["off_index_out_of_range"] = ("mesh.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
                                       r"face indices span \[0, 3\] but the mesh has 3")
    files["ply_truncated"] = ("mesh.ply", _ply_binary(TRIANGLE, [(0, 1, 2)])[:-7],
                              r"the file ends early \(its PLY header declares 3 vertices")
    files["ply_infinite_vertices"] = ("mesh.ply", _ply_ascii(["0 0 0", "inf 0 0", "0 1 0"],
                                                             ["3 0 1 2"]),
                                      r"1 of 3 vertices are NaN or infinite")
    files["obj_index_out_of_range"] = ("mesh.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
                                       r"face indices span \[0, 8\] but the mesh has 3")
    files["stl_truncated"] = ("mesh.stl", b"\0" * 80 + struct.pack("<I", 4) + b"\0" * 60,
                              r"the file ends early \(its STL header declares 4 triangles")
    out = {}
    for case, (name, content, words) in files.items():
        sub = folder / case
        sub.mkdir(parents=True, exist_ok=True)
        path = sub / name
        if isinstance(content, str):
            path.write_text(content)
        else:
            path.write_bytes(content)
        if case == "gltf_short_bin":
            (sub / "mesh.bin").write_bytes(data[:20])
        out[case] = (path, words)
    return out
