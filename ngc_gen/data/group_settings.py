"""Settings dataclasses of the data layer built from their config group: the values a config
gives, the rest from the group's YAML in conf/ (the one place a default lives); a key the
group's YAML does not have is refused, never dropped."""
from __future__ import annotations

import dataclasses

from ngc_gen.conf.defaults import unknown_keys, yaml_settings
from ngc_gen.data.errors import DataError


def from_group(cls, d, file: str, node: str | None = None, field: str = ""):
    """`cls` from config mapping `d` (a composed group, or some of its keys; None: none) of
    conf/<file> (`node`); the group's keys that are not fields of `cls` (what its runner or a
    sibling settings class reads) are left to them. An unknown key is a DataError naming it
    (`field`.<key>) and the file."""
    d = dict(d or {})
    bad = unknown_keys(d, file, node)
    if bad:
        raise DataError(f"unknown key{'s' if len(bad) > 1 else ''} {', '.join(map(repr, bad))}",
                        path=f"conf/{file}", field=f"{field}.{bad[0]}" if field else bad[0],
                        fix=f"use the keys of conf/{file}" + (f" ({node})" if node else ""))
    names = {f.name for f in dataclasses.fields(cls)}
    return yaml_settings(cls, file, node, **{k: v for k, v in d.items() if k in names})
