"""The interactive GC editor (docs/editor.md): `EditorSession` is the document (an edit
program) and its state machine, testable without a browser; `EditorServer` shows it in the
browser with viser; `serve(cfg)` is `edit.py viewer=true`."""
from .library import ShapeLibrary
from .limits import Limits
from .session import EditorSession, Outcome
from .start import open_session

__all__ = ["EditorSession", "Limits", "Outcome", "ShapeLibrary", "open_session"]
