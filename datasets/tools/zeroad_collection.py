"""A user-style collection from the 0 A.D. quadrupeds (docs/zeroad.md): `--n` meshes of
different species at rest, each turned by a seeded random rotation (any direction), written as
<name>.ply into OUT with nothing else: what `make demo-collection` gives
`train.py experiment=collection`.

    python datasets/tools/zeroad_collection.py OUT [--n 12] [--seed 0] [--cache-dir .cache]

The first build of the 0 A.D. collection fetches the `0ad-data` package once (apt-get download,
or ZEROAD_DEB=<the .deb>); the art is CC-BY-SA 3.0, Wildfire Games.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cache-dir", type=Path, default=ROOT / ".cache")
    args = ap.parse_args()

    import numpy as np
    import trimesh
    from scipy.spatial.transform import Rotation

    from ngc_gen.data.atomic import atomic_write
    from ngc_gen.data.rigs.zeroad import zeroad_quadrupeds

    rng = np.random.default_rng(args.seed)
    meshes = zeroad_quadrupeds(args.cache_dir)
    by_species = {}
    for m in meshes:
        by_species.setdefault(m.species, []).append(m)
    species = sorted(by_species)
    chosen = [by_species[s][0] for s in rng.permutation(species)[:args.n]]
    if len(chosen) < args.n:  # fewer species than asked: more meshes of the same ones
        rest = [m for m in meshes if m not in chosen]
        chosen += [rest[i] for i in rng.permutation(len(rest))[:args.n - len(chosen)]]
    args.out.mkdir(parents=True, exist_ok=True)
    for m, R in zip(chosen, Rotation.random(len(chosen), random_state=args.seed).as_matrix()):
        mesh = trimesh.Trimesh(m.rig.posed() @ R.T, m.rig.faces, process=False)
        atomic_write(args.out / f"{m.name}.ply", lambda f, x=mesh: f.write(x.export(file_type="ply")))
        print(f"{m.name} ({m.species})")
    print(f"{len(chosen)} meshes, turned at random (seed {args.seed}), in {args.out}")


if __name__ == "__main__":
    main()
