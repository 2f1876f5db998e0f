"""The shapes an editor session can open and take parts from.

A fit checkpoint's shapes (`load_shapes`), plus shapes made during the session (samples and
interpolations of a generation run) that no checkpoint holds yet. A saved program names its
shape and its mix sources by name; `edit.py` resolves them in one checkpoint, so saving a program
on a session-made shape also writes a checkpoint holding the shapes it names
(`write_checkpoint`).
"""
from __future__ import annotations

from pathlib import Path

from ngc_gen.data.annotations import rounded_gc_dict
from ngc_gen.edit import EditError
from ngc_gen.geometry import GeneralizedCylinder
from ngc_gen.shape import Shape

from ..runtime.mix_sources import MixSources


def as_written(shape: Shape) -> Shape:
    """The shape with its GCs as a checkpoint stores them (numbers rounded by
    `rounded_gc_dict`), so a program saved on it replays on the written checkpoint exactly."""
    gcs = [GeneralizedCylinder.from_dict(rounded_gc_dict(g.to_dict())) for g in shape.gcs]
    return shape.replaced(gcs=gcs)


class ShapeLibrary:
    """shapes: {name: Shape} of `checkpoint` (a fit-format checkpoint, or None); `add` puts a
    session-made shape beside them."""

    def __init__(self, shapes: dict[str, Shape], checkpoint: str | Path | None = None):
        self.shapes = dict(shapes)
        self.checkpoint = None if checkpoint is None else Path(checkpoint)
        self.stored = set(shapes) if checkpoint is not None else set()

    @property
    def names(self) -> list[str]:
        return list(self.shapes)

    def __getitem__(self, name: str) -> Shape:
        if name not in self.shapes:
            raise EditError(f"unknown shape; the editor has {self.names}", field="shape",
                            value=name)
        return self.shapes[name]

    def __contains__(self, name) -> bool:
        return name in self.shapes

    def add(self, shape: Shape) -> Shape:
        """Keep a session-made shape (GCs rounded as a checkpoint stores them); returns it."""
        shape = as_written(shape)
        self.shapes[shape.name] = shape
        self.stored.discard(shape.name)
        return shape

    def resolver(self, target: Shape) -> MixSources:
        """`SourceResolver` for mixes into `target` from this library's shapes (the one
        resolver edit.py uses too; sources in other checkpoints are refused)."""
        return MixSources(self.shapes, target, checkpoint=None, where="the editor has")

    def needs_checkpoint(self, names) -> bool:
        """True if a program naming these shapes cannot replay on `checkpoint` as it is."""
        return self.checkpoint is None or any(n not in self.stored for n in names)

    def write_checkpoint(self, path: Path, names: list[str], source: str = "") -> Path:
        """A fit-format checkpoint (the first shape's decoder) holding shapes `names`, which
        `edit.py run=<path>` opens."""
        from ngc_gen.generate import WrittenShape, write_edit_checkpoint

        shapes = [self[n] for n in dict.fromkeys(names)]
        written = [WrittenShape(s.name, Path(path).with_suffix(f".{s.name}.ply"),
                                Path(path), s.codes, [g.to_dict() for g in s.gcs], 0)
                   for s in shapes]
        return write_edit_checkpoint(Path(path), shapes[0].decoder, written, source=source)
