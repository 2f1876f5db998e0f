"""The body frame a shape is written in: which way is up and which way it faces.

An annotation records it as its top-level `frame` (docs/gcs.md):

    frame: {up: [0, 1, 0], front: [0, 0, 1], from_mesh: [[3x3]], source: detected}

`up` and `front` are the body's axes in the written (annotated) coordinates; `from_mesh` (optional)
the rotation R taking the mesh file's own coordinates to the written ones, before `normalize`;
`source` (optional) how it was found (detected | given | override | dataset | model). left is
up x front. Normalisation is a similarity without rotation, so a frame holds before and after
it. A collection trains one generator only when all its shapes share up and front
(`collection_frame`); the generator then records that frame and every picture, edit and sample
of it uses it. Torch-free: checked before heavy imports (numpy loads only to read a frame).
"""
from __future__ import annotations

import math

from ngc_gen.data.errors import DataError

FRAME_KEYS = ("up", "front", "from_mesh", "source")
SOURCES = ("detected", "given", "override", "dataset", "model")
# two shapes share a frame when their up and front agree to this angle (degrees)
SAME_FRAME_DEGREES = 1.0


def _unit(v, path, fld: str) -> list[float]:
    import numpy as np

    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (3,) or not np.isfinite(a).all() or np.linalg.norm(a) == 0:
        raise DataError(f"frame.{fld} must be three numbers [x, y, z], not zero, got {v!r}",
                        path=path, field=f"frame.{fld}", fix="e.g. frame: {up: [0, 1, 0], "
                        "front: [0, 0, 1]}")
    a = a / np.linalg.norm(a)
    return [float(x) for x in a]


def read_frame(f, path=None) -> dict | None:
    """An annotation's `frame` value checked: {up, front} unit and orthogonal, `from_mesh` a
    rotation, `source` one of SOURCES. None stays None. DataError naming the file and field."""
    import numpy as np

    if f is None:
        return None
    if not isinstance(f, dict) or not {"up", "front"} <= set(f) or set(f) - set(FRAME_KEYS):
        raise DataError(f"frame must be a mapping {{up, front[, from_mesh, source]}}, got {f!r}",
                        path=path, field="frame", fix="e.g. frame: {up: [0, 1, 0], "
                        "front: [0, 0, 1]}, or leave it out")
    up, front = _unit(f["up"], path, "up"), _unit(f["front"], path, "front")
    if abs(float(np.dot(up, front))) > 1e-3:
        raise DataError(f"frame.up {list(up)} and frame.front {list(front)} are not "
                        f"perpendicular", path=path, field="frame",
                        fix="give two perpendicular directions (up [0, 1, 0], front [0, 0, 1])")
    out = {"up": up, "front": front}
    if f.get("from_mesh") is not None:
        try:
            R = np.asarray(f["from_mesh"], dtype=np.float64)
        except (TypeError, ValueError):
            R = None
        if R is None or R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-4) \
                or np.linalg.det(R) < 0:
            raise DataError(f"frame.from_mesh must be a 3x3 rotation, got {f['from_mesh']!r}",
                            path=path, field="frame.from_mesh",
                            fix="rows [[..], [..], [..]] of a rotation, or leave it out")
        out["from_mesh"] = [[float(x) for x in row] for row in R]
    if f.get("source") is not None:
        if f["source"] not in SOURCES:
            raise DataError(f"frame.source must be one of {', '.join(SOURCES)}, got "
                            f"{f['source']!r}", path=path, field="frame.source")
        out["source"] = str(f["source"])
    return out


def frame_dict(frame: dict | None) -> dict | None:
    """A frame as YAML/JSON-safe lists (None stays None)."""
    if frame is None:
        return None
    return {k: (list(v) if k in ("up", "front") else v) for k, v in frame.items()}


def body_axes(frame: dict) -> dict[str, np.ndarray]:
    """{forward, up, left} unit (3,) float64 vectors of a frame (left = up x front)."""
    import numpy as np

    up = np.asarray(frame["up"], dtype=np.float64)
    front = np.asarray(frame["front"], dtype=np.float64)
    return {"forward": front, "up": up, "left": np.cross(up, front)}


def _angle(a, b) -> float:
    """Degrees between two 3-vectors (pure Python: the preflight runs before numpy loads)."""
    na, nb = math.sqrt(sum(x * x for x in a)), math.sqrt(sum(x * x for x in b))
    c = sum(x * y for x, y in zip(a, b)) / max(na * nb, 1e-300)
    return math.degrees(math.acos(max(-1.0, min(1.0, c))))


def _rounded(v) -> list[float]:
    n = math.sqrt(sum(x * x for x in v)) or 1.0
    return [round(x / n, 3) + 0.0 for x in v]


def collection_frame(frames: list[tuple[str, dict | None]]) -> dict | None:
    """The one frame of a collection: {up, front} shared by every shape, or None when no shape
    records one (frames as `read_frame` gives them, or raw {up, front} of an annotation file). DataError naming two shapes when they differ, or when some record a frame and
    others do not (a folder mixing annotated and unannotated orientations)."""
    given = [(n, f) for n, f in frames if f is not None]
    if not given:
        return None
    missing = [n for n, f in frames if f is None]
    fix = ("annotate the whole folder with one template (python train.py stage=annotate "
           "data=folder data.path=DIR annotate.template=T), which writes every mesh in the "
           "template's frame, or add `frame: {up, front}` to the YAMLs without one")
    if missing:
        raise DataError(f"{len(missing)} of {len(frames)} shapes record no body frame (e.g. "
                        f"{missing[0]}) while {given[0][0]} does: the collection mixes frames",
                        field="frame", fix=fix)
    name0, f0 = given[0]
    for n, f in given[1:]:
        if _angle(f["up"], f0["up"]) > SAME_FRAME_DEGREES or \
                _angle(f["front"], f0["front"]) > SAME_FRAME_DEGREES:
            raise DataError(f"{n} is written facing {_rounded(f['front'])}, up "
                            f"{_rounded(f['up'])}, but {name0} facing {_rounded(f0['front'])}, "
                            f"up {_rounded(f0['up'])}, with no rotation recorded between them: "
                            f"one generator needs one body frame", field="frame", fix=fix)
    return {"up": [float(x) for x in f0["up"]], "front": [float(x) for x in f0["front"]]}


def shared_frame(frames: list[dict | None]) -> dict | None:
    """The frame every one of `frames` shares, or None (none recorded, or they differ): what a
    picture of several shapes can stand on."""
    try:
        return collection_frame([(str(i), f) for i, f in enumerate(frames)])
    except DataError:
        return None
