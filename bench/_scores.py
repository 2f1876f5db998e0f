"""Scores of GCs against ground-truth GCs that more than one bench reads.

`truth_purity`: per true GC, the share of the surface samples that belong to it (the true GC
they are relatively nearest to) inside the GC of the same index, as bench/transfer.py scores a
transfer against the rig GCs; `truth_scores` adds each curve end's distance from the true one.
"""
from __future__ import annotations


def truth_purity(truth_gcs, gcs, points):
    """(G,) purity of `gcs` against `truth_gcs` (same order) on surface `points` (N, 3); NaN
    where no sample belongs to a true GC."""
    import numpy as np

    from ngc_gen.data.autogc.coverage import rho_matrix
    from ngc_gen.data.mesh.sampling import gc_membership

    part = rho_matrix(truth_gcs, points)[0].argmin(0)
    pp, pg, _ = gc_membership(points, gcs)
    inside = np.zeros((len(points), len(gcs)), bool)
    inside[pp, pg] = True
    return np.array([inside[part == g, g].mean() if (part == g).any() else np.nan
                     for g in range(len(truth_gcs))])


def truth_scores(truth_gcs, gcs, points):
    """(purity (G,), endpoint errors (2G,)) of `gcs` against `truth_gcs`, same order: an
    endpoint error is the distance of a curve end from the true GC's, over its arc length."""
    import numpy as np

    errs = []
    for t, g in zip(truth_gcs, gcs):
        ct, cg = t.centre_line(65), g.centre_line(65)
        length = np.linalg.norm(np.diff(ct, axis=0), axis=1).sum()
        errs += [np.linalg.norm(ct[0] - cg[0]) / length, np.linalg.norm(ct[-1] - cg[-1]) / length]
    return truth_purity(truth_gcs, gcs, points), np.array(errs)
