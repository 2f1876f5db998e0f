"""How a template is put on a mesh (TransferSettings) and what comes out (Transfer)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ngc_gen.conf.defaults import yaml_settings
from ngc_gen.data.autogc.orient import Orientation, parse_axis
from ngc_gen.data.autogc.skeleton import BACKENDS
from ngc_gen.data.errors import DataError
from ngc_gen.data.group_settings import from_group
from ngc_gen.geometry import GeneralizedCylinder


@dataclass(frozen=True)
class TransferSettings:
    """How a template is put on a mesh: keys of the `annotate` group, whose values live in
    conf/annotate/default.yaml (`from_yaml`, `from_config`). See that file for what each field
    means."""

    resolution: int
    samples: int
    skeleton: str
    margin: float
    min_branch_length: float
    max_gcs: int
    seed: int
    up: str
    front: str
    missing_cost: float
    max_match_cost: float
    min_matched: float
    refine_steps: int
    min_tube: float
    min_confidence: float
    hug: bool
    hug_quantile: float

    def __post_init__(self):
        checks = {"resolution": self.resolution >= 16, "samples": self.samples >= 100,
                  "skeleton": self.skeleton in BACKENDS, "margin": self.margin >= 0,
                  "missing_cost": self.missing_cost > 0, "max_match_cost": self.max_match_cost > 0,
                  "min_matched": 0 <= self.min_matched <= 1, "refine_steps": self.refine_steps >= 0,
                  "min_tube": 0 <= self.min_tube < 1,
                  "min_confidence": 0 <= self.min_confidence < 1,
                  "hug": isinstance(self.hug, bool), "hug_quantile": 0.5 <= self.hug_quantile <= 1}
        for name, ok in checks.items():
            if not ok:
                raise DataError(f"invalid value {getattr(self, name)!r}", field=f"annotate.{name}",
                                fix="resolution >= 16; samples >= 100; skeleton auto|cgal|voxel; "
                                    "margin >= 0; missing_cost, max_match_cost > 0; min_matched "
                                    "in [0, 1]; refine_steps >= 0; min_tube, min_confidence in [0, 1); "
                                    "hug true|false; hug_quantile in [0.5, 1]")
        for name in ("up", "front"):
            parse_axis(getattr(self, name), f"annotate.{name}")

    @classmethod
    def from_yaml(cls, **overrides) -> "TransferSettings":
        """conf/annotate/default.yaml's values, some replaced by `overrides`."""
        return yaml_settings(cls, "annotate/default.yaml", **overrides)

    @classmethod
    def from_config(cls, d) -> "TransferSettings":
        """From the `annotate` group (or some of its keys; the rest: its YAML's); its keys that
        are not these settings' are the runner's or `AutoGCSettings`'; an unknown key is a
        DataError."""
        return from_group(cls, d, "annotate/default.yaml", field="annotate")


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
