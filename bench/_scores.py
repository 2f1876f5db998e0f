"""Scores of GCs against ground-truth GCs that more than one bench reads.

`truth_purity`: per true GC, the share of the surface samples that belong to it (the true GC
they are relatively nearest to) inside the GC of the same index, as bench/transfer.py scores a
transfer against the rig GCs.
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
