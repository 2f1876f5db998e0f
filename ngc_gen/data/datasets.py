"""Datasets: each resolves to a list of shape annotations (mesh + GCs) to prepare and fit.

Instantiated from `conf/data/*.yaml` by Hydra (`_target_`). `shapes()` is the one method the
rest of the pipeline uses.
"""
from __future__ import annotations

from pathlib import Path

from ngc_gen.data.annotations import Annotation, load_annotation
from ngc_gen.data.autogc.auto import AutoGCSettings, auto_annotation
from ngc_gen.data.errors import DataError
from ngc_gen.data.mesh_folder import mesh_files, run_annotations



class AnnotatedShapes:
    """A fixed list of annotation YAML files (the shipped `ant` and `airplane`)."""

    def __init__(self, name: str, annotations: list[str]):
        self.name = name
        self.annotations = [Path(a) for a in annotations]

    def shapes(self) -> list[Annotation]:
        return [load_annotation(a) for a in self.annotations]


class SingleGC:
    """Another dataset's meshes with one automatic GC each instead of their annotations (the
    paper's single-GC variant: `ant_1gc`)."""

    def __init__(self, name: str, base):
        self.name, self.base = name, base

    def shapes(self) -> list[Annotation]:
        axis = AutoGCSettings.from_yaml(method="axis")
        return [auto_annotation(a.mesh, name=a.name, bound=a.bound, settings=axis)
                for a in self.base.shapes()]


class Combined:
    """Several datasets fitted together (e.g. the ant plus a few creatures)."""

    def __init__(self, name: str, parts: list):
        self.name, self.parts = name, list(parts)

    def shapes(self) -> list[Annotation]:
        out = [a for p in self.parts for a in p.shapes()]
        names = [a.name for a in out]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise DataError(f"shape names {dup} appear in more than one part of {self.name}",
                            fix="rename the shapes so every name is unique")
        return out


class MeshFolder:
    """Any directory of meshes; `<name>.yaml` beside a mesh annotates it, else automatic GCs
    made with `annotate` (the `annotate` config group; default: one GC per limb or part). A
    folder with annotations and no meshes (a `stage=annotate` run directory) is its
    annotations."""

    def __init__(self, name: str, path: str, bound: float = 0.8, annotate=None):
        self.name = name
        self.path = Path(path)
        self.bound = bound
        self.annotate = annotate
        self.settings = AutoGCSettings.from_config(annotate)

    def mesh_files(self) -> list[Path]:
        """The folder's mesh files, sorted by name."""
        return mesh_files(self.path)

    def shapes(self) -> list[Annotation]:
        annotated = run_annotations(self.path)  # a stage=annotate run directory
        if annotated:
            return [load_annotation(a) for a in annotated]
        out = []
        for mesh in self.mesh_files():
            yml = mesh.with_suffix(".yaml")
            out.append(load_annotation(yml) if yml.exists()
                       else auto_annotation(mesh, bound=self.bound, settings=self.settings))
        return out


class Creatures:
    """Procedural creatures (our RaBit stand-in), built once into `out_dir` and reused."""

    def __init__(self, name: str, out_dir: str, n: int = 64, seed: int = 0,
                 split: str = "train", test_fraction: float = 0.25, limit: int | None = None):
        if split not in ("train", "test", "all"):
            raise DataError(f"creatures split must be train, test or all, got {split!r}")
        self.name, self.out_dir, self.n, self.seed = name, Path(out_dir), n, seed
        self.split, self.test_fraction, self.limit = split, test_fraction, limit

    def shapes(self) -> list[Annotation]:
        from ngc_gen.data.procedural.creatures import build_creatures, creature_names, creature_split

        split = creature_split(creature_names(self.n), self.seed, self.test_fraction)
        names = split["train"] + split["test"] if self.split == "all" else split[self.split]
        names = names[: self.limit] if self.limit else names
        # only the shapes asked for are built (the demo's 3 of 64)
        build_creatures(self.out_dir, self.n, seed=self.seed, test_fraction=self.test_fraction,
                        only=names)
        return [load_annotation(self.out_dir / f"{n}.yaml") for n in names]

