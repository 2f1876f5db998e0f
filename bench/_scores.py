"""Scores of GCs against ground-truth GCs that more than one bench reads.

`truth_purity`: per true GC, the share of the surface samples that belong to it inside the GC
of the same index, as bench/transfer.py scores a transfer against the rig GCs; a sample belongs
to the rig GC its skin weights give it where the truth keeps them (`skin_parts`: the 0 A.D.
collection), else to the true GC it is relatively nearest to. `truth_scores` adds each curve
end's distance from the true one.
"""
from __future__ import annotations


def skin_parts(owner_file, vertices, points, names):
    """(N,) index into `names` of the rig GC whose skin weights hold each of `points` (that of
    its nearest mesh vertex; -1: a GC not in `names`), from an .owner.npz (`names`, `owner`
    per vertex of the mesh whose `vertices` (V, 3) are given, in the same order)."""
    import numpy as np
    from scipy.spatial import cKDTree

    with np.load(owner_file) as z:
        rig_names, owner = [str(n) for n in z["names"]], z["owner"]
    if len(owner) != len(vertices):
        raise ValueError(f"{owner_file}: {len(owner)} owners for {len(vertices)} vertices")
    to = np.array([names.index(n) if n in names else -1 for n in rig_names])
    return to[owner[cKDTree(vertices).query(points)[1]]]


def truth_purity(truth_gcs, gcs, points, part=None):
    """(G,) purity of `gcs` against `truth_gcs` (same order) on surface `points` (N, 3); NaN
    where no sample belongs to a true GC. `part` (N,): the true GC of each sample (the rig's
    skin, `skin_parts`); None: the true GC it is relatively nearest to."""
    import numpy as np

    from ngc_gen.data.autogc.coverage import rho_matrix
    from ngc_gen.data.mesh.sampling import gc_membership

    if part is None:
        part = rho_matrix(truth_gcs, points)[0].argmin(0)
    pp, pg, _ = gc_membership(points, gcs)
    inside = np.zeros((len(points), len(gcs)), bool)
    inside[pp, pg] = True
    return np.array([inside[part == g, g].mean() if (part == g).any() else np.nan
                     for g in range(len(truth_gcs))])


def truth_scores(truth_gcs, gcs, points, part=None):
    """(purity (G,), endpoint errors (2G,)) of `gcs` against `truth_gcs`, same order (`part`:
    as `truth_purity`): an endpoint error is the distance of a curve end from the true GC's,
    over its arc length."""
    import numpy as np

    errs = []
    for t, g in zip(truth_gcs, gcs):
        ct, cg = t.centre_line(65), g.centre_line(65)
        length = np.linalg.norm(np.diff(ct, axis=0), axis=1).sum()
        errs += [np.linalg.norm(ct[0] - cg[0]) / length, np.linalg.norm(ct[-1] - cg[-1]) / length]
    return truth_purity(truth_gcs, gcs, points, part), np.array(errs)
