"""The defaults of the project's config groups, read from the checkout's conf/ YAML (the one
place a default lives) for callers that build settings without a composed config: the library
(`extract_mesh`, `prepare_shape`, `auto_gcs`, ... without settings), notebooks and tests.
Torch-free: yaml only, so it is cheap to import anywhere."""
from __future__ import annotations

import copy
import dataclasses
import functools
from pathlib import Path

import yaml

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"  # beside train.py, edit.py, sample.py


@functools.lru_cache(maxsize=None)
def _read(file: str) -> dict:
    return yaml.safe_load((CONF_DIR / file).read_text()) or {}


def group_defaults(file: str, node: str | None = None) -> dict:
    """The mapping of conf/<file> (a dotted `node` inside it: "sparse", "gcs"), a fresh copy."""
    d = _read(file)
    for part in node.split(".") if node else ():
        d = d[part]
    return copy.deepcopy(d)


def yaml_settings(cls, file: str, node: str | None = None, **overrides):
    """`cls` (a settings dataclass) with its fields' values from conf/<file> (`node`), some
    replaced by `overrides`; the group's other keys (`_target_`, what its runner reads) are
    not the settings'. A field the YAML lacks is a KeyError naming it and the file."""
    d = group_defaults(file, node)
    names = [f.name for f in dataclasses.fields(cls)]
    missing = [n for n in names if n not in d]
    if missing:
        raise KeyError(f"conf/{file}{':' + node if node else ''} has no {', '.join(missing)} "
                       f"(the defaults of {cls.__name__})")
    return cls(**{**{n: d[n] for n in names}, **overrides})


def unknown_keys(d, file: str, node: str | None = None) -> list[str]:
    """The keys of config mapping `d` that conf/<file> (`node`) does not have: what its group
    does not know (a typo, a key of another group)."""
    known = group_defaults(file, node)
    return sorted(str(k) for k in dict(d or {}) if k not in known)
