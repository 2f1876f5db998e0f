"""One body frame for a collection: the rotation that writes a mesh in its template's frame.

A transferred mesh is written in the template's frame (`frame: {up, front}` of the template;
the quadruped's is y up, +z front), whatever way the mesh file faces: the annotation records

    frame: {up: [0, 1, 0], front: [0, 0, 1], from_mesh: [[3 x 3]], source: detected|given|override}

with written coordinates = from_mesh @ (the mesh file's coordinates), then the usual
`normalize` (docs/gcs.md). This module holds the rotation arithmetic, the candidate frames the
transfer tries on a mesh in any orientation, the frame a match implies (Wahba's problem on its
parts' directions), and the user's per-mesh override.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ngc_gen.data.autogc.orient import Orientation, parse_axis
from ngc_gen.data.errors import DataError

SOURCES = ("detected", "given", "override")
FOLDER_FILE = "frames.yaml"  # one file for the folder: {"*": {up, front}, <mesh name>: {up, front}}


def to_template(orientation: Orientation, template_frame: Orientation) -> np.ndarray:
    """(3, 3) R with R @ (a direction in the mesh's coordinates) = the same direction in the
    template's frame: the mesh's front, left, up go to the template's."""
    return template_frame.matrix.T @ orientation.matrix


def angle_deg(R: np.ndarray) -> float:
    """The angle of rotation R (3, 3) in degrees."""
    c = (float(np.trace(R)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def record(orientation: Orientation, template_frame: Orientation, source: str) -> dict:
    """The annotation's `frame` key for a mesh of this orientation (module docstring)."""
    R = to_template(orientation, template_frame)
    return {"up": [float(x) for x in template_frame.up], "front": [float(x) for x in template_frame.front],
            "from_mesh": [[round(float(x), 9) for x in row] for row in R], "source": source}


def pca_candidates(points: np.ndarray) -> list[Orientation]:
    """Frames along the surface's principal axes, for a mesh in any orientation: front along
    the longest (either sign) or the second (a giraffe is taller than long), up along either
    sign of each other axis: 16 right-handed frames, the true one among them up to the pose."""
    X = np.asarray(points, dtype=np.float64)
    X = X - X.mean(0)
    _, vecs = np.linalg.eigh(X.T @ X / len(X))
    axes = vecs[:, ::-1].T                                   # rows: longest first
    out = []
    for f in (0, 1):
        for u in (a for a in range(3) if a != f):
            for sf in (1.0, -1.0):
                for su in (1.0, -1.0):
                    out.append(Orientation(su * axes[u], sf * axes[f], ("detected", "detected")))
    return out


def wahba(world: np.ndarray, body: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(3, 3) rotation O (rows front, left, up) with O @ world_i closest to body_i: the frame
    in which the matched parts' directions (world (K, 3)) point where the template's do (body
    (K, 3), unit), weighted (K,) (Markley's SVD solution)."""
    w = world / np.maximum(np.linalg.norm(world, axis=1, keepdims=True), 1e-12)
    b = body / np.maximum(np.linalg.norm(body, axis=1, keepdims=True), 1e-12)
    B = (weight[:, None, None] * b[:, :, None] * w[:, None, :]).sum(0)
    U, _, Vt = np.linalg.svd(B)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def orientation_of(O: np.ndarray, source: tuple[str, str]) -> Orientation:
    """The Orientation whose matrix is the rotation O (rows front, left, up)."""
    return Orientation(np.asarray(O[2], dtype=np.float64), np.asarray(O[0], dtype=np.float64), source)


def distinct(orientations: list[Orientation], within_deg: float = 15.0) -> list[Orientation]:
    """The orientations with those within `within_deg` of an earlier one left out."""
    if not orientations:
        return []
    M = np.stack([o.matrix for o in orientations])             # (n, 3, 3), built once
    kept: list[int] = []
    for i in range(len(M)):   # greedy in order: a loop over the candidates, each against all kept
        tr = np.einsum("ij,kij->k", M[i], M[kept])               # trace(M_i @ M_k.T)
        ang = np.degrees(np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0)))
        if np.all(ang > within_deg):
            kept.append(i)
    return [orientations[i] for i in kept]


def override_orientation(spec, where, field: str = "frame") -> Orientation:
    """A user's frame override {up: <axis>, front: <axis>} in the mesh file's coordinates (a
    signed axis such as +y or a vector). DataError (one line) naming `where` otherwise."""
    if not isinstance(spec, dict) or set(spec) - {"up", "front"} or not {"up", "front"} <= set(spec):
        raise DataError(f"a frame override must be {{up: <axis>, front: <axis>}}, got {spec!r}",
                        path=where, field=field, fix="write e.g. frame: {up: +y, front: -z}")
    try:
        up = parse_axis(spec["up"], f"{field}.up")
        front = parse_axis(spec["front"], f"{field}.front")
    except DataError as e:
        raise DataError(e.what, path=where, field=e.field, fix=e.fix) from None
    if up is None or front is None or abs(float(up @ front)) > 1e-3:
        raise DataError(f"frame override up {spec['up']!r} and front {spec['front']!r} must be two "
                        "perpendicular directions", path=where, field=field,
                        fix="give two different axes, e.g. frame: {up: +y, front: -z}")
    return Orientation(up, front, ("override", "override"))


def read_override(mesh_file: str | Path) -> tuple[Orientation | None, str | None]:
    """The frame override for one mesh file: `frame: {up, front}` (the mesh file's axes) in the
    YAML beside it, or a recorded frame there marked `source: override`, else its entry (or
    "*") in the folder's frames.yaml; (None, None) when there is none. Raises DataError (one
    line) when the override cannot be read."""
    import yaml

    mesh_file = Path(mesh_file)
    beside = mesh_file.with_suffix(".yaml")
    for path, pick in ((beside, lambda d: d.get("frame")),
                       (mesh_file.parent / FOLDER_FILE,
                        lambda d: d.get(mesh_file.stem, d.get("*")))):
        if not path.is_file():
            continue
        try:
            d = yaml.safe_load(path.read_text(encoding="utf-8"))
        except yaml.YAMLError as e:
            raise DataError(f"cannot read YAML ({str(e).splitlines()[0]})", path=path,
                            fix="fix the YAML syntax") from None
        spec = pick(d) if isinstance(d, dict) else None
        if spec is None:
            continue
        if isinstance(spec, dict) and "from_mesh" in spec:  # a recorded frame: an override
            if spec.get("source") != "override":             # only when marked so by hand
                continue
            R = np.asarray(spec["from_mesh"], dtype=np.float64)
            tf = Orientation(np.asarray(spec["up"], float), np.asarray(spec["front"], float))
            O = tf.matrix @ R
            return orientation_of(O, ("override", "override")), str(path)
        return override_orientation(spec, path), str(path)
    return None, None


def rotated_mesh(mesh, R: np.ndarray):
    """The mesh (trimesh) with every vertex turned by R: R @ v."""
    import trimesh

    return trimesh.Trimesh(np.asarray(mesh.vertices, np.float64) @ np.asarray(R).T,
                           np.asarray(mesh.faces), process=False)


def moved_gcs(gcs: list, R: np.ndarray, center: np.ndarray, scale: float) -> list:
    """GCs under x -> (R @ x - center) * scale: curves turned and moved, radii and caps scaled,
    up turned; relative coordinates of a point and its image agree."""
    from ngc_gen.data.annotations import similar_gc_dict
    from ngc_gen.geometry import GeneralizedCylinder

    out = []
    for g in gcs:
        d = g.to_dict()
        d = {**d, "curve": {**d["curve"], "points": (np.asarray(d["curve"]["points"], np.float64)
                                                     @ np.asarray(R).T).tolist()},
             "up": (np.asarray(R) @ np.asarray(d["up"], np.float64)).tolist()}
        out.append(GeneralizedCylinder.from_dict(similar_gc_dict(d, center, scale)))
    return out


def written(raw, own_center: np.ndarray, own_scale: float, gcs: list, R: np.ndarray,
            bound: float | None):
    """(mesh, GCs) in the written frame: the raw mesh file's mesh turned by R, then normalised
    into `bound`; `gcs` were found on the raw mesh normalised in its own frame
    ((raw - own_center) * own_scale)."""
    from ngc_gen.data.mesh.io import normalize

    mesh, c2, s2 = normalize(rotated_mesh(raw, R), bound)
    # x_own = (raw - c1) s1 and w = (R raw - c2) s2, so w = (R x_own - s1 (c2 - R c1)) s2 / s1
    shift = own_scale * (np.asarray(c2) - np.asarray(R) @ np.asarray(own_center))
    return mesh, moved_gcs(gcs, R, shift, s2 / own_scale)
