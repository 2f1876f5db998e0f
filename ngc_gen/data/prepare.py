"""Turn an annotated mesh into cached training samples (docs/fitting.md).

Per shape: normalise the mesh, check that the GC union covers its surface, sample near-surface
points (surface + normal * N(0, offset_std)) and volume points uniform in the GC union, compute
the solid's signed distance (winding-number sign; surface samples and distances from the faces
of the solid's boundary, not from faces inside another closed piece: mesh/sdf.py) and the
relative coordinates of every sample in every GC that contains it. The result is one npz per shape, written atomically and keyed by a hash of
(mesh bytes, annotation, settings): an unchanged shape is loaded, any change re-prepares, and the
training loop does no geometry.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import re
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from ngc_gen.conf.defaults import yaml_settings
from ngc_gen.data.annotations import Annotation, annotation_from_dict, load_annotation
from ngc_gen.data.atomic import atomic_write
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh.io import load_mesh
from ngc_gen.data.mesh.sampling import gc_membership, sample_surface, sample_volume
from ngc_gen.data.mesh.sdf import signed_distance, solid_surface
from ngc_gen.geometry import GeneralizedCylinder

log = logging.getLogger(__name__)

CACHE_VERSION = 2  # bump when the cached arrays or their meaning change (2: the solid's SDF)


@dataclass(frozen=True)
class PrepareSettings:
    """How many samples of which kind; every field is part of the cache key.

    n_samples: training samples per shape; surface_fraction of them are near-surface
    (surface point + normal * N(0, offset_std); a list of stds: equal shares of each, as
    DeepSDF's two), the rest uniform in the GC union
    (volume_region="gcs", what NGC trains on) or in the box [-1, 1]^3 (volume_region="box",
    DeepSDF's own sampling: a world-space SDF must learn the empty space too).
    coverage_samples exact surface points measure coverage; below min_coverage preparation stops.
    pair_margin: a sample trains a GC's network up to relative radius 1 + pair_margin, a band
    past the GC's boundary that the union never reads from that GC; so at the boundary, where
    the union hands over to another GC, the network is not at the edge of what it learned
    (docs/fitting.md, "Seams").
    shell_fraction of the volume samples (volume_region="gcs") lie in the GCs' outer shells,
    relative radius in [1 - shell_width, 1], the rest uniform in the union: where a GC's field
    fades out in the blended union, and where a GC that alone holds a point must not dip
    below zero far from the surface (a floater). overlap_fraction of them lie where two or more
    GCs overlap (uniform there), taken from the uniform share.
    """

    n_samples: int
    surface_fraction: float
    offset_std: float | tuple[float, ...]
    coverage_samples: int
    min_coverage: float
    seed: int
    volume_region: str
    pair_margin: float
    shell_fraction: float
    shell_width: float
    overlap_fraction: float

    @classmethod
    def from_yaml(cls, **overrides) -> "PrepareSettings":
        """The values of conf/prepare/default.yaml (the one place they live), some replaced by
        `overrides`."""
        return yaml_settings(cls, "prepare/default.yaml", **overrides)

    def __post_init__(self):
        if isinstance(self.offset_std, (list, tuple)):
            object.__setattr__(self, "offset_std", tuple(float(s) for s in self.offset_std))
        stds = self.offset_std if isinstance(self.offset_std, tuple) else (self.offset_std,)
        checks = {
            "n_samples": self.n_samples >= 1,
            "surface_fraction": 0.0 <= self.surface_fraction <= 1.0,
            "offset_std": len(stds) > 0 and min(stds) >= 0.0,
            "coverage_samples": self.coverage_samples >= 1,
            "min_coverage": 0.0 <= self.min_coverage <= 1.0,
            "volume_region": self.volume_region in ("gcs", "box"),
            "pair_margin": 0.0 <= self.pair_margin <= 1.0,
            "shell_fraction": 0.0 <= self.shell_fraction <= 1.0,
            "shell_width": 0.0 < self.shell_width <= 1.0,
            "overlap_fraction": (0.0 <= self.overlap_fraction
                                 and self.shell_fraction + self.overlap_fraction <= 1.0),
        }
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"prepare.{name}",
                                fix="n_samples, coverage_samples >= 1; volume_region gcs or box; surface_fraction, min_coverage, "
                                    "pair_margin, shell_fraction in [0, 1]; shell_width in (0, 1]; "
                                    "overlap_fraction >= 0 with shell_fraction + overlap_fraction <= 1; "
                                    "offset_std >= 0")


@dataclass
class PreparedShape:
    """Cached training data of one shape (arrays as stored in the npz).

    points (M, 3) f32 samples in the normalised frame, the first n_surface near-surface;
    sdf (M,) f32, negative inside; pair_point (P,) i64, pair_gc (P,) i64, pair_rel (P, 3) f32:
    sample pair_point[i] lies inside GC pair_gc[i] at relative coords [u, a, b] (a sample in
    k GCs has k pairs, one in none has none); gc_names (G,); coverage of the surface by the GC
    union; mesh_vertices (V, 3) f64 / mesh_faces (F, 3) i64: the normalised mesh, with
    ``normalised = (original - center) * scale``.
    """

    name: str
    key: str
    points: np.ndarray
    sdf: np.ndarray
    n_surface: int
    pair_point: np.ndarray
    pair_gc: np.ndarray
    pair_rel: np.ndarray
    gc_names: list[str]
    annotation_yaml: str
    coverage: float
    mesh_vertices: np.ndarray
    mesh_faces: np.ndarray
    center: np.ndarray
    scale: float
    settings: dict
    path: Path | None = field(default=None, compare=False)
    from_cache: bool = field(default=False, compare=False)

    def annotation(self) -> Annotation:
        """The annotation the samples were made from (mesh as an absolute path or resource)."""
        return annotation_from_dict(yaml.safe_load(self.annotation_yaml))

    def gcs(self) -> list[GeneralizedCylinder]:
        """The shape's GCs, in the order pair_gc indexes them."""
        return self.annotation().gcs


_ARRAYS = ("points", "sdf", "pair_point", "pair_gc", "pair_rel", "mesh_vertices", "mesh_faces", "center")
_SCALARS = {"name": str, "key": str, "annotation_yaml": str, "coverage": float, "scale": float, "n_surface": int}


def cache_key(mesh_bytes: bytes, annotation: Annotation, settings: PrepareSettings) -> str:
    """sha256 over the mesh file bytes, the annotation content (not its mesh path, so moving a
    dataset keeps its cache; of its body frame only the rotation from the mesh's coordinates,
    which moves the samples: up and front name directions, they move nothing) and the
    settings."""
    content = annotation.to_dict()
    content.pop("mesh")
    rotation = (content.pop("frame", None) or {}).get("from_mesh")
    if rotation is not None:
        content["from_mesh"] = rotation
    h = hashlib.sha256()
    h.update(f"ngc-gen-prepare-v{CACHE_VERSION}".encode())
    h.update(hashlib.sha256(mesh_bytes).digest())
    h.update(json.dumps(content, sort_keys=True).encode())
    fields = dataclasses.asdict(settings)
    if not fields["pair_margin"]:   # added later: samples without a margin keep their keys
        fields.pop("pair_margin")
    if not fields["shell_fraction"]:   # added later: samples without shells keep their keys
        fields.pop("shell_fraction")
        fields.pop("shell_width")
    if not fields["overlap_fraction"]:   # added later: samples without it keep their keys
        fields.pop("overlap_fraction")
    h.update(json.dumps(fields, sort_keys=True).encode())
    return h.hexdigest()


def cache_path(cache_dir: str | os.PathLike, name: str) -> Path:
    """One npz per shape name: ``<cache_dir>/<name>.npz`` (unsafe characters replaced)."""
    return Path(cache_dir) / (re.sub(r"[^A-Za-z0-9._-]", "_", name) + ".npz")


def load_prepared(path: str | os.PathLike) -> PreparedShape:
    """Load a prepared-shape npz (raises DataError if it is missing, corrupt or incomplete)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in _ARRAYS}
            scalars = {k: t(z[k][()]) for k, t in _SCALARS.items()}
            gc_names = [str(s) for s in z["gc_names"]]
            settings = json.loads(str(z["settings_json"][()]))
            version = int(z["cache_version"][()])
    except FileNotFoundError as e:
        raise DataError("prepared cache file not found", path=path, fix="run preparation first") from e
    except (KeyError, ValueError, OSError, zipfile.BadZipFile, EOFError) as e:
        raise DataError(f"prepared cache file is unreadable or incomplete ({type(e).__name__}: {e})",
                        path=path, fix="delete it; the next preparation rewrites it") from e
    if version != CACHE_VERSION:
        raise DataError(f"cache format v{version}, this code reads v{CACHE_VERSION}", path=path,
                        fix="delete it; the next preparation rewrites it")
    return PreparedShape(**arrays, **scalars, gc_names=gc_names, settings=settings, path=path)


def _stored_key(path: Path) -> str | None:
    """The key inside an existing cache file, or None if there is none or it is unreadable."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return str(z["key"][()])
    except (FileNotFoundError, KeyError, ValueError, OSError, zipfile.BadZipFile, EOFError):
        return None


def _save(shape: PreparedShape, path: Path) -> None:
    arrays = {k: getattr(shape, k) for k in _ARRAYS}
    scalars = {k: np.array(getattr(shape, k)) for k in _SCALARS}
    extra = {
        "gc_names": np.array(shape.gc_names, dtype=str),
        "settings_json": np.array(json.dumps(shape.settings, sort_keys=True)),
        "cache_version": np.array(CACHE_VERSION),
    }
    atomic_write(path, lambda f: np.savez(f, **arrays, **scalars, **extra))


def _gap_to_gc(gc: GeneralizedCylinder, q: np.ndarray) -> np.ndarray:
    """World distance (N,) from points q (N, 3) outside ``gc`` to its boundary along the ray
    from the GC's core (axis point, or end centre past a cap): (1 - 1/rho) |q - core|, where
    rho = sqrt(max(|u|-1, 0)^2 + a^2 + b^2) is 1 on the boundary. An upper bound of the true
    distance, in the normalised frame, comparable between GCs of different sizes."""
    rel = np.asarray(gc.to_relative(q))
    rho = np.sqrt(GeneralizedCylinder.relative_measure(rel))
    core = np.asarray(gc.to_world(np.stack([np.clip(rel[:, 0], -1.0, 1.0), 0 * rho, 0 * rho], axis=1)))
    gap = np.clip(1.0 - 1.0 / np.maximum(rho, 1e-12), 0.0, None) * np.linalg.norm(q - core, axis=1)
    return np.where(np.isfinite(gap), gap, np.inf)


def _coverage_error(ann: Annotation, uncovered: np.ndarray, n_total: int, coverage: float,
                    min_coverage: float) -> DataError:
    """DataError naming the GC nearest to the uncovered surface points (uncovered: (U, 3))."""
    gap = np.stack([_gap_to_gc(gc, uncovered) for gc in ann.gcs])  # (G, U)
    nearest = gap.argmin(axis=0)
    counts = np.bincount(nearest, minlength=len(ann.gcs))
    order = [int(g) for g in np.argsort(-counts, kind="stable") if counts[g] > 0]
    top = order[0]
    mine = nearest == top
    lo, hi = uncovered[mine].min(axis=0), uncovered[mine].max(axis=0)
    others = ", ".join(f"'{ann.gcs[g].name}' ({counts[g]})" for g in order[1:4])
    what = (f"the GCs cover only {coverage:.4%} of the mesh surface (need {min_coverage:.4%}): "
            f"{len(uncovered)} of {n_total} surface samples are outside every GC; nearest GC "
            f"'{ann.gcs[top].name}' for {counts[top]} of them (up to {gap[top, mine].max():.3g} outside "
            f"it), its missed points lie in the box "
            f"{np.round(lo, 3).tolist()}..{np.round(hi, 3).tolist()}"
            + (f"; also near {others}" if others else ""))
    where = ann.source if ann.source is not None else f"automatic annotation of {ann.mesh}"
    return DataError(what, path=where, gc=ann.gcs[top].name, field="gcs",
                     fix=f"enlarge the radii or caps of '{ann.gcs[top].name}', move its curve "
                         f"towards those points, or add a GC there ("
                         + ("coordinates are the mesh's own: normalize is false)"
                            if ann.bound is None else
                            f"coordinates are normalised: the mesh is fitted into "
                            f"[-{ann.bound:g}, {ann.bound:g}]^3)"))


def _in_context(e: DataError, ann: Annotation) -> DataError:
    """The same error, also naming the annotation whose mesh it concerns."""
    owner = ann.source if ann.source is not None else f"automatic annotation '{ann.name}'"
    return DataError(f"{e.what} (mesh of {owner})", path=e.path or ann.mesh, gc=e.gc,
                     field=e.field or "mesh", fix=e.fix)


def compute_prepared(ann: Annotation, settings: PrepareSettings, key: str = "") -> PreparedShape:
    """Sample one shape (no cache involved); raises DataError on bad data or low coverage."""
    rng = np.random.default_rng(settings.seed)
    try:
        mesh, center, scale = ann.load_mesh()
        V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        exact, _ = sample_surface(V, F, settings.coverage_samples, rng)
    except DataError as e:
        raise _in_context(e, ann) from e
    gcs = ann.gcs

    covered = np.zeros(len(exact), dtype=bool)
    covered[gc_membership(exact, gcs)[0]] = True
    coverage = float(covered.mean())
    if coverage < settings.min_coverage:
        raise _coverage_error(ann, exact[~covered], len(exact), coverage, settings.min_coverage)

    n_surface = int(round(settings.n_samples * settings.surface_fraction))
    solid = solid_surface(V, F)   # less the faces inside other closed pieces (mesh/sdf.py)
    surf, normals = sample_surface(*solid, n_surface, rng)
    if isinstance(settings.offset_std, tuple):  # a mixture: sample i gets std i mod k
        stds = np.asarray(settings.offset_std)[np.arange(n_surface) % len(settings.offset_std)]
        surf += normals * (rng.normal(0.0, 1.0, size=(n_surface, 1)) * stds[:, None])
    else:
        surf += normals * rng.normal(0.0, settings.offset_std, size=(n_surface, 1))
    margin = settings.pair_margin
    if settings.volume_region == "box":
        vol = rng.uniform(-1.0, 1.0, (settings.n_samples - n_surface, 3))
        vp, vg, vr = gc_membership(vol, gcs, margin=margin)
    else:
        vol, (vp, vg, vr) = union_volume(gcs, settings, settings.n_samples - n_surface, rng)
        if margin:   # the same points, also paired with the GCs whose margin holds them
            vp, vg, vr = gc_membership(vol, gcs, margin=margin)
    sp, sg, sr = gc_membership(surf, gcs, margin=margin)
    points = np.concatenate([surf, vol])
    sdf = signed_distance(points, V, F, distance_mesh=solid)
    return PreparedShape(
        name=ann.name, key=key,
        points=points.astype(np.float32), sdf=sdf.astype(np.float32), n_surface=n_surface,
        pair_point=np.concatenate([sp, vp + n_surface]).astype(np.int64),
        pair_gc=np.concatenate([sg, vg]).astype(np.int64),
        pair_rel=np.concatenate([sr, vr]).astype(np.float32),
        gc_names=ann.gc_names, annotation_yaml=ann.to_yaml(), coverage=coverage,
        mesh_vertices=V.astype(np.float64), mesh_faces=F.astype(np.int64),
        center=np.asarray(center, dtype=np.float64), scale=float(scale),
        settings=dataclasses.asdict(settings),
    )


def union_volume(gcs: list, settings: PrepareSettings, n: int, rng: np.random.Generator):
    """n volume samples in the GC union, shell_fraction of them in the GCs' outer shells
    (`sample_volume` with `shell`) and overlap_fraction where GCs overlap (`overlap`), with
    their membership pairs."""
    n_shell = int(round(n * settings.shell_fraction))
    n_overlap = int(round(n * settings.overlap_fraction))
    parts = [sample_volume(gcs, n - n_shell - n_overlap, rng)]
    if n_shell:
        parts.append(sample_volume(gcs, n_shell, rng, shell=settings.shell_width))
    if n_overlap:
        parts.append(sample_volume(gcs, n_overlap, rng, overlap=True))
    if len(parts) == 1:
        return parts[0]
    starts = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    return (np.concatenate([v for v, _ in parts]),
            (np.concatenate([pp + s for (_, (pp, _, _)), s in zip(parts, starts)]),
             np.concatenate([pg for _, (_, pg, _) in parts]),
             np.concatenate([pr for _, (_, _, pr) in parts])))


def prepare_shape(annotation: Annotation | str | os.PathLike, settings: PrepareSettings | None = None,
                  cache_dir: str | os.PathLike | None = None) -> PreparedShape:
    """Prepared samples of one shape, from ``cache_dir`` if an up-to-date npz is there.

    annotation: an Annotation or the path of its YAML. With cache_dir None nothing is written.
    On any DataError (missing/empty/NaN mesh, bad annotation, coverage below
    settings.min_coverage) no cache file is written. Logs one line with coverage and counts.
    """
    ann = annotation if isinstance(annotation, Annotation) else load_annotation(annotation)
    settings = settings or PrepareSettings.from_yaml()
    try:
        mesh_file = ann.mesh_path
        if not mesh_file.is_file():
            load_mesh(mesh_file)  # raises the DataError that explains the missing file
    except DataError as e:
        raise _in_context(e, ann) from e
    key = cache_key(mesh_file.read_bytes(), ann, settings)
    path = None if cache_dir is None else cache_path(cache_dir, ann.name)
    if path is not None and _stored_key(path) == key:
        shape = load_prepared(path)
        shape.from_cache = True
        shape.annotation_yaml = ann.to_yaml()  # the frame as the annotation records it now
        log.info("%s: cached %s (coverage %.4f%%)", ann.name, path, 100 * shape.coverage)
        return shape
    start = time.perf_counter()
    shape = compute_prepared(ann, settings, key)
    if path is not None:
        _save(shape, path)
        shape.path = path
    inside = np.zeros(len(shape.points), dtype=bool)
    inside[shape.pair_point] = True
    log.info("%s: coverage %.4f%%, %d samples (%d near-surface, %d volume, %d in no GC), "
             "%d GC pairs over %d GCs, %.2f s%s", ann.name, 100 * shape.coverage, len(shape.points),
             shape.n_surface, len(shape.points) - shape.n_surface, int((~inside).sum()),
             len(shape.pair_point), len(shape.gc_names), time.perf_counter() - start,
             f" -> {path}" if path is not None else "")
    return shape


def _prepare_in_worker(args) -> float | None:
    """Seconds to prepare and cache one shape in a worker process; None if it failed (the
    caller prepares that shape again in its own process, which raises the error)."""
    annotation, settings, cache_dir = args
    start = time.perf_counter()
    try:
        prepare_shape(annotation, settings, cache_dir)
    except Exception:  # noqa: BLE001 (reported by the caller's own attempt)
        return None
    return time.perf_counter() - start


def prepare_uncached(annotations: list[Annotation], settings: PrepareSettings,
                     cache_dir: str | os.PathLike, workers: int | None = None) -> dict[str, float]:
    """Prepare into `cache_dir`, in worker processes (`map_shapes`), the shapes whose cache file
    is missing or stale; {name: seconds} of those made. `prepare_shape` then reads them from the
    cache. A shape that fails is left to the caller's `prepare_shape`, which raises its error."""
    from ngc_gen.data.workers import map_shapes, worker_count

    def stale(ann: Annotation) -> bool:
        if not ann.mesh_path.is_file():
            return False  # prepare_shape explains it
        return _stored_key(cache_path(cache_dir, ann.name)) != cache_key(
            ann.mesh_path.read_bytes(), ann, settings)

    todo = [a for a in annotations if stale(a)]
    if worker_count(len(todo), workers) <= 1:
        return {}  # the caller's own prepare_shape makes them: no save-then-load round trip
    seconds = map_shapes(_prepare_in_worker, [(a, settings, cache_dir) for a in todo], workers)
    return {a.name: s for a, s in zip(todo, seconds) if s is not None}
