"""Write the shipped multi-GC annotations of pyvista's ant and airplane.

    python datasets/tools/annotate_pieces.py      # rewrites datasets/{ant,airplane}/*.yaml

Both meshes are made of separate pieces (the ant: 15 intersecting closed pieces; the airplane:
fuselage, wings, stabilisers, fins). Each piece gets one curved GC fitted by
`ngc_gen.data.autogc.fit_gc.fit_gc`; the names come from where each piece sits (rules below, checked
by looking at the meshes: the ant faces +z with y up, the airplane's nose points to -y with z up).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from ngc_gen.data.annotations import Annotation, save_annotation  # noqa: E402
from ngc_gen.data.autogc.fit_gc import fit_gc  # noqa: E402
from ngc_gen.data.mesh.io import load_mesh, normalize  # noqa: E402
from ngc_gen.data.mesh.sampling import sample_surface  # noqa: E402
from ngc_gen.geometry import GeneralizedCylinder  # noqa: E402


def ant_name(lo, hi):
    c = (lo + hi) / 2
    side = "l" if c[0] > 0 else "r"  # facing +z with y up, +x is the ant's left
    if hi[0] - lo[0] > 0.5:  # legs reach far out along x; numbered front (1) to back (3)
        return f"leg_{side}{1 if c[2] > 0.05 else 2 if c[2] > -0.15 else 3}"
    if hi[2] > 0.7:
        return f"antenna_{side}"
    if hi[2] < -0.2:
        return "abdomen"
    if lo[2] > 0.44:
        return f"mandible_{side}"
    if lo[2] > 0.3:
        return f"eye_{side}"
    return "head" if c[2] > 0.2 else "thorax"


def airplane_name(lo, hi):
    c = (lo + hi) / 2
    side = "l" if c[0] > 0 else "r"  # nose towards -y with z up: +x is the left
    if hi[1] - lo[1] > 1.0:
        return "fuselage"
    if hi[0] - lo[0] > 0.5:
        return f"wing_{side}"
    if hi[2] - lo[2] > 0.1:
        return f"fin_{side}"
    return f"stabilizer_{side}"


def rounded(x, digits: int = 4, up: bool = False):
    """Round every float of a GC dict for readable YAML; radii and caps round up so the GC
    can only grow."""
    if isinstance(x, dict):
        return {k: rounded(v, digits, up=k in ("caps", "radii")) for k, v in x.items()}
    if isinstance(x, list):
        return [rounded(v, digits, up) for v in x]
    if isinstance(x, float):
        return float(np.ceil(x * 10 ** digits) / 10 ** digits) if up else round(x, digits)
    return x


def annotate(name: str, rule, degree_of) -> Path:
    mesh, _, _ = normalize(load_mesh(f"pyvista:{name}.ply"), 0.8)
    rng = np.random.default_rng(0)
    gcs = []
    for piece in mesh.split(only_watertight=False):
        if piece.area <= 1e-4 * mesh.area:
            continue
        part = rule(*piece.bounds)
        n = max(200, int(20000 * piece.area / mesh.area))
        pts = np.concatenate([piece.vertices, sample_surface(piece.vertices, piece.faces, n, rng)[0]])
        gc = GeneralizedCylinder.from_dict(rounded(fit_gc(pts, part, degree=degree_of(part))
                                                   .to_dict()))
        assert np.asarray(gc.contains(pts)).all(), f"rounding let {part} lose points"
        gcs.append(gc)
    names = [g.name for g in gcs]
    assert len(set(names)) == len(names), f"two pieces got the same name: {sorted(names)}"
    order = sorted(range(len(gcs)), key=lambda i: names[i])
    ann = Annotation(name=name, mesh=f"pyvista:{name}.ply", gcs=[gcs[i] for i in order], bound=0.8)
    path = ROOT / "datasets" / name / f"{name}.yaml"
    save_annotation(ann, path)
    return path


if __name__ == "__main__":
    print(annotate("ant", ant_name, lambda p: 2 if p.startswith(("eye", "mandible")) else 3))
    print(annotate("airplane", airplane_name, lambda p: 2 if p != "fuselage" else 3))
