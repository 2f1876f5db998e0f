"""An annotation file's YAML as plain data, with the one-line errors a user can act on (file
missing, malformed YAML with its line and column, not UTF-8). PyYAML only, so the check before
torch loads (`ngc_gen.app.runtime.checks`) and the full reader (`annotations.load_annotation`)
share it."""
from __future__ import annotations

from pathlib import Path

import yaml

from ngc_gen.data.errors import DataError
from ngc_gen.values import load_yaml


def read_annotation_yaml(path) -> object:
    """The parsed YAML of the annotation at `path` (any YAML value: the caller checks its
    shape); DataError naming the file otherwise."""
    path = Path(path)
    if not path.is_file():
        raise DataError("annotation file not found", path=path, fix="check the path")
    try:
        return load_yaml(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or " ".join(str(e).split())
        fix = ("remove or rename one of the two entries" if "appears twice" in problem
               else "correct the YAML syntax (indentation, brackets, 'key: value')")
        raise DataError(f"malformed YAML{where}: {problem}", path=path, fix=fix) from None
    except UnicodeDecodeError as e:
        raise DataError(f"not a UTF-8 text file ({e})", path=path,
                        fix="save the annotation as UTF-8 YAML") from None
