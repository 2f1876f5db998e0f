"""What a dataset config's files say before anything heavy loads: each annotation YAML parses
and names its mesh and GCs, each mesh file exists and its header declares triangles
(`mesh.header`), GC names are unique. Standard library, PyYAML and the data layer's light
modules only: `train.py` runs it before numpy, trimesh and torch load, so a bad mesh or GC file
fails in a second with the words the full check (`load_annotation`, `load_mesh`) would use.
"""
from __future__ import annotations

from pathlib import Path

from ngc_gen.data.annotation_file import read_annotation_yaml
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.header import check_mesh_file
from ngc_gen.data.mesh_folder import mesh_files, run_annotations

RESOURCE_PREFIXES = ("pyvista:",)  # shipped meshes (`mesh.io.RESOURCE_SCHEMES`): read later


def _mesh_of(mesh: Path, owner) -> None:
    try:
        check_mesh_file(mesh)
    except DataError as e:  # the words of prepare's `_in_context`
        raise DataError(f"{e.what} (mesh of {owner})", path=e.path, field="mesh",
                        fix=e.fix) from None


def check_annotation_file(path) -> None:
    """An annotation YAML (docs/gcs.md): a mapping with `mesh` and a non-empty `gcs` list of
    uniquely named GCs, whose mesh file passes `check_mesh_file`. DataError naming the file."""
    path = Path(path)
    d = read_annotation_yaml(path)
    if not isinstance(d, dict):
        return  # load_annotation explains what an annotation must be
    gcs = d.get("gcs")
    if isinstance(gcs, list):
        names = [g.get("name") for g in gcs if isinstance(g, dict)]
        dupes = sorted({str(n) for n in names if n is not None and names.count(n) > 1})
        if dupes:
            raise DataError(f"GC names {dupes} appear more than once", path=path, gc=dupes[0],
                            field="name", fix="give every GC a unique name")
    mesh = d.get("mesh")
    if isinstance(mesh, str) and mesh and not mesh.startswith(RESOURCE_PREFIXES):
        file = Path(mesh).expanduser()
        _mesh_of(file if file.is_absolute() else path.parent / file, path)


def check_data(node) -> None:
    """Every file a `data` config (conf/data/*.yaml, resolved to a dict) will read: the
    annotations of AnnotatedShapes, the meshes (and annotations beside them) of MeshFolder,
    the parts of Combined and the base of SingleGC. Generated datasets (Creatures) have no
    user files."""
    if isinstance(node, list):
        for part in node:
            check_data(part)
        return
    if not isinstance(node, dict):
        return
    target = str(node.get("_target_", "")).rsplit(".", 1)[-1]
    if target == "AnnotatedShapes":
        for a in node.get("annotations") or []:
            check_annotation_file(a)
    elif target == "MeshFolder" and run_annotations(node["path"]):
        for a in run_annotations(node["path"]):
            check_annotation_file(a)
    elif target == "MeshFolder":
        for mesh in mesh_files(node["path"]):
            yml = mesh.with_suffix(".yaml")
            if yml.exists():
                check_annotation_file(yml)
            else:
                _mesh_of(mesh, f"automatic annotation '{mesh.stem}'")
    elif target == "Combined":
        check_data(node.get("parts"))
    elif target == "SingleGC":
        check_data(node.get("base"))


def check_frames(node) -> None:
    """The annotation files a MeshFolder or AnnotatedShapes config reads share one body frame
    (`body_frame.collection_frame` on their `frame` keys, YAML only): what a generator needs,
    refused in a second instead of after the meshes are read. A mesh without a YAML has no
    frame of its own and does not count."""
    from ngc_gen.data.body_frame import collection_frame

    if not isinstance(node, dict):
        return
    target = str(node.get("_target_", "")).rsplit(".", 1)[-1]
    if target == "AnnotatedShapes":
        files = [Path(a) for a in node.get("annotations") or []]
    elif target == "MeshFolder":
        files = run_annotations(node["path"]) or [
            m.with_suffix(".yaml") for m in mesh_files(node["path"])
            if m.with_suffix(".yaml").exists()]
    else:
        return
    frames = []
    for f in files:
        d = read_annotation_yaml(f)
        frame = d.get("frame") if isinstance(d, dict) else None
        ok = isinstance(frame, dict) and all(
            isinstance(frame.get(k), list) and len(frame[k]) == 3 for k in ("up", "front"))
        frames.append((f.stem, frame if ok else None))
    collection_frame(frames)
