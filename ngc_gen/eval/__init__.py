"""Evaluation metrics: fitting (Table 1) and its junctions, deformation (Tables 2-3), generation
(Sec. 4.4).

Depends only on numpy, scipy, trimesh and torch. Every function states its convention.
"""

from ngc_gen.eval.deformation import volume_area_change
from ngc_gen.eval.fitting import (chamfer, chamfer_l1, component_sizes, emd, fragments, fscore,
                                  hausdorff, mesh_chamfer, normal_consistency,
                                  point_mesh_distance, reconstruction_metrics)
from ngc_gen.eval.junctions import junction_metrics
from ngc_gen.eval.generation import generation_metrics, metrics_from_distances, pairwise_chamfer
from ngc_gen.eval.point_samples import sample_boundary, sample_point_clouds, sample_surface

__all__ = [
    "sample_surface", "sample_boundary", "sample_point_clouds",
    "reconstruction_metrics", "chamfer", "chamfer_l1", "hausdorff", "emd", "fscore",
    "normal_consistency", "mesh_chamfer", "point_mesh_distance", "fragments", "component_sizes",
    "volume_area_change", "junction_metrics",
    "pairwise_chamfer", "generation_metrics", "metrics_from_distances",
]
