"""How a template is put on a mesh (TransferSettings) and what comes out (Transfer)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ngc_gen.data.autogc.orient import Orientation, parse_axis
from ngc_gen.data.autogc.skeleton import BACKENDS
from ngc_gen.data.errors import DataError
from ngc_gen.geometry import GeneralizedCylinder


@dataclass(frozen=True)
class TransferSettings:
    """How a template is put on a mesh; the defaults are conf/annotate/default.yaml's (a test
    checks they agree). See that file for what each field means."""

    resolution: int = 96
    samples: int = 20000
    skeleton: str = "auto"
    margin: float = 0.05
    min_branch_length: float = 1.0
    max_gcs: int = 24
    seed: int = 0
    up: str = "auto"
    front: str = "auto"
    missing_cost: float = 6.0
    max_match_cost: float = 4.0
    min_matched: float = 0.6
    refine_steps: int = 60
    min_tube: float = 0.22
    min_confidence: float = 0.05

    def __post_init__(self):
        checks = {"resolution": self.resolution >= 16, "samples": self.samples >= 100,
                  "skeleton": self.skeleton in BACKENDS, "margin": self.margin >= 0,
                  "missing_cost": self.missing_cost > 0, "max_match_cost": self.max_match_cost > 0,
                  "min_matched": 0 <= self.min_matched <= 1, "refine_steps": self.refine_steps >= 0,
                  "min_tube": 0 <= self.min_tube < 1,
                  "min_confidence": 0 <= self.min_confidence < 1}
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"annotate.{name}",
                                fix="resolution >= 16; samples >= 100; skeleton auto|cgal|voxel; "
                                    "margin >= 0; missing_cost, max_match_cost > 0; min_matched "
                                    "in [0, 1]; refine_steps >= 0; min_tube, min_confidence in [0, 1)")
        for name in ("up", "front"):
            parse_axis(getattr(self, name), f"annotate.{name}")

    @classmethod
    def from_config(cls, d) -> "TransferSettings":
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in dict(d).items() if k in names})


@dataclass
class Transfer:
    """The template's GCs on one mesh (template order) and how they were found."""

    gcs: list[GeneralizedCylinder]
    matched: list[str]
    missing: list[str]
    cost: float
    orientation: Orientation
    coverage: float
    rotation: np.ndarray   # (3, 3): the template's frame = rotation @ this mesh's (frame.py)
    confidence: float      # orientation.Choice.confidence
    warnings: list[str]    # a given axis overruled
    source: str            # the frame: detected | given | override
