"""An editor session from edit.py's config: the checkpoint's shapes (and a generation run's),
the shape to open, an optional starting program, the limits."""
from __future__ import annotations

from ngc_gen.data.errors import DataError

from ..runtime.checkpoints import fit_checkpoint
from ..runtime.programs import program_from_config
from .latent import LatentShapes
from .library import ShapeLibrary
from .limits import Limits
from .session import EditorSession


def limits_from_config(editor) -> Limits:
    lim = editor.limits
    return Limits(min_radius=float(lim.min_radius), max_twist=float(lim.max_twist),
                  min_point_gap=float(lim.min_point_gap), bound=float(editor.bound))


def open_session(cfg) -> tuple[EditorSession, LatentShapes | None]:
    """(session, latent shapes or None) for `edit.py viewer=true run=... [shape=...]`
    [`editor.generator=<diffusion run>`] [`program_file=... | edit=...`: the starting program]."""
    from ngc_gen.shape import load_shapes

    editor = cfg.editor
    if cfg.get("run") is None and editor.get("generator") is None:
        raise DataError("no run given", field="run",
                        fix="pass run=<fit run dir or checkpoint, or a sample.py output dir> "
                            "or editor.generator=<diffusion run>")
    library = ShapeLibrary({})
    if cfg.get("run") is not None:
        path = fit_checkpoint(cfg.run)
        library = ShapeLibrary(load_shapes(path), path)
    latent = None
    if editor.get("generator") is not None:
        from ngc_gen.generate import load_generator

        latent = LatentShapes(load_generator(editor.generator), library)
        if not library.names:
            latent.training()
    program = None
    if cfg.get("program_file") is not None or cfg.get("edit") is not None:
        from ngc_gen.edit.program import EditProgram

        program = EditProgram(**program_from_config(cfg))
    shape = cfg.get("shape") or (program.shape if program is not None else None) \
        or library.names[0]
    if shape not in library:
        raise DataError(f"no shape named {shape!r}; the checkpoint holds {library.names}",
                        field="shape", fix="pass shape=<one of those names>")
    kw = {}
    if program is not None:
        kw = dict(name=program.name, description=program.description,
                  smooth_union=program.smooth_union, ops=program.ops)
    session = EditorSession(library, shape, limits_from_config(editor),
                            pose_at=list(editor.pose_at), chunk=int(editor.chunk),
                            **{"name": str(editor.name), **kw})
    return session, latent
