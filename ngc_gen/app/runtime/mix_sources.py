"""The one resolver of an edit program's mix sources, for edit.py and the editor.

A `mix` op names its source part as (shape, gc, ckpt): a shape of the edited collection
(shape None: the edited shape itself) or of another fit checkpoint. Features mix only within one
network, so every source is checked to come from the edited shape's decoder (same config, equal
weights). edit.py allows other checkpoints; the editor, which mixes among the shapes it has
open, does not (`checkpoint=None`).
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ngc_gen.edit.errors import EditError

from .checkpoints import fit_checkpoint


def same_network(a, b) -> bool:
    """True if two decoders are one object or have the same config and equal weights."""
    import torch

    if a is b:
        return True
    if getattr(a, "config", None) != getattr(b, "config", None):
        return False
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


class MixSources:
    """`SourceResolver` for mixes into `target`: (shape, gc, ckpt) -> MixSource.

    shapes: {name: Shape} of the edited collection (read at each call, so shapes added later,
      as the editor does, are found); checkpoint: the file those shapes came from, or None to
      refuse sources from other checkpoints; where: how an error names the collection."""

    def __init__(self, shapes: Mapping, target, checkpoint: str | Path | None = None,
                 where: str = "the checkpoint holds"):
        self.shapes, self.target, self.where = shapes, target, where
        self.checkpoint = None if checkpoint is None else Path(checkpoint).resolve()
        self._other: dict[Path, dict] = {}

    def _collection(self, ckpt) -> tuple[Mapping, str]:
        """(shapes, label suffix) a source's ckpt names."""
        if ckpt is None:
            return self.shapes, ""
        if self.checkpoint is None:
            raise EditError("the editor mixes parts of the shapes it has open, not of other "
                            "checkpoints", field="source.ckpt", value=ckpt,
                            fix="drop source.ckpt (edit.py runs such programs)")
        from ngc_gen.data.errors import DataError
        from ngc_gen.lit.checkpoint import load_autodecoder
        from ngc_gen.shape import shapes_from_autodecoder

        try:
            path = fit_checkpoint(ckpt).resolve()  # a run directory or a checkpoint file
        except DataError as e:
            raise EditError(str(e), field="source.ckpt", value=str(ckpt)) from None
        if path == self.checkpoint:
            return self.shapes, ""
        if path not in self._other:
            try:
                other = load_autodecoder(path)
            except DataError as e:
                raise EditError(str(e), field="source.ckpt", value=str(ckpt)) from None
            if other.hparams.kind != "ngc" or not same_network(other.decoder,
                                                               self.target.decoder):
                raise EditError("this checkpoint's network differs from the edited one's, so "
                                "its part features do not mean the same", field="source.ckpt",
                                value=str(ckpt),
                                fix="mix parts fitted with one network (the same run, or a "
                                    "codes-only fit with the decoder frozen)")
            self._other[path] = shapes_from_autodecoder(other)
        return self._other[path], f" ({ckpt})"

    def __call__(self, shape: str | None, gc: str, ckpt: str | None):
        from ngc_gen.edit.program import MixSource

        shapes, suffix = self._collection(ckpt)
        name = shape or self.target.name
        if name not in shapes:
            where = "the checkpoint holds" if suffix else self.where
            raise EditError(f"unknown shape; {where} {list(shapes)}", field="source.shape",
                            value=name)
        src = shapes[name]
        if gc not in src.gc_names:
            raise EditError(f"shape '{name}' has no GC named so; its GCs are {src.gc_names}",
                            field="source.gc", value=gc)
        if not same_network(src.decoder, self.target.decoder):
            raise EditError(f"shape '{name}' comes from another network, so its part "
                            "features do not mean the same", field="source.shape", value=name,
                            fix="mix parts of shapes of one run")
        j = src.index(gc)
        return MixSource(src.codes[j].clone(), src.gcs[j], f"{name}/{gc}{suffix}")
