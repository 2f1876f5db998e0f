"""The package read as a reviewer reads it: no function over 80 lines (numba kernels aside), no
module over 500 lines, and no settings dataclass with defaults of its own where its config
group has a YAML (the YAML is the one source of a default)."""
from __future__ import annotations

import ast
import dataclasses
import importlib
from pathlib import Path

import yaml

from .helpers import ROOT

MAX_FUNCTION, MAX_MODULE = 80, 500

# Known exceptions: none left, and nothing may be added.
LONG_MODULES: set[str] = set()
LONG_FUNCTIONS: set[str] = set()
# settings whose group has a YAML but which still carry defaults
SETTINGS_WITH_DEFAULTS: set[str] = set()
# how a settings class built from its group's YAML without `_target_` says so
FROM_GROUP = ("from_config", "from_yaml")


def modules() -> list[Path]:
    return sorted((ROOT / "ngc_gen").rglob("*.py"))


def njit(fn: ast.FunctionDef) -> bool:
    return any("njit" in ast.unparse(d) for d in fn.decorator_list)


def long_functions(path: Path) -> list[str]:
    rel = path.relative_to(ROOT).as_posix()
    return [f"{rel}:{n.name}" for n in ast.walk(ast.parse(path.read_text()))
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            and n.end_lineno - n.lineno + 1 > MAX_FUNCTION and not njit(n)]


def test_no_function_is_over_80_lines():
    found = {f for p in modules() for f in long_functions(p)}
    assert found <= LONG_FUNCTIONS, sorted(found - LONG_FUNCTIONS)
    assert found == LONG_FUNCTIONS, f"done: take {sorted(LONG_FUNCTIONS - found)} off the list"


def test_no_module_is_over_500_lines():
    found = {p.relative_to(ROOT).as_posix() for p in modules()
             if len(p.read_text().splitlines()) > MAX_MODULE}
    assert found == LONG_MODULES, sorted(found ^ LONG_MODULES)


def test_the_size_check_finds_a_long_function(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION))
    (tmp_path / "m.py").write_text(f"def f():\n{body}\n\n\n@numba.njit\ndef k():\n{body}\n")
    found = [ast.unparse(n.decorator_list[0]) if n.decorator_list else n.name
             for n in ast.walk(ast.parse((tmp_path / "m.py").read_text()))
             if isinstance(n, ast.FunctionDef) and n.end_lineno - n.lineno + 1 > MAX_FUNCTION
             and not njit(n)]
    assert found == ["f"]


def configured_dataclasses() -> dict[str, list[str]]:
    """{dotted class: [YAML files]} of every `_target_` under conf/ that is a dataclass."""
    targets: dict[str, list[str]] = {}

    def walk(node, where):
        if isinstance(node, dict):
            if isinstance(node.get("_target_"), str):
                targets.setdefault(node["_target_"], []).append(where)
            for v in node.values():
                walk(v, where)
        elif isinstance(node, list):
            for v in node:
                walk(v, where)

    for p in sorted((ROOT / "conf").rglob("*.yaml")):
        walk(yaml.safe_load(p.read_text()), p.relative_to(ROOT).as_posix())
    out = {}
    for target, where in targets.items():
        module, _, name = target.rpartition(".")
        obj = getattr(importlib.import_module(module), name)
        if dataclasses.is_dataclass(obj):
            out[f"{obj.__module__}.{obj.__qualname__}"] = where
    return out


def group_dataclasses() -> set[str]:
    """Dotted names of the package's dataclasses built from a config group without `_target_`
    (a `from_config` or `from_yaml` classmethod)."""
    out = set()
    for p in modules():
        module = ".".join(p.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ClassDef) \
                    and any("dataclass" in ast.unparse(d) for d in node.decorator_list) \
                    and any(isinstance(f, ast.FunctionDef) and f.name in FROM_GROUP
                            for f in node.body):
                out.add(f"{module}.{node.name}")
    return out


def defaults(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)
            if f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING]


def test_settings_built_from_a_yaml_have_no_defaults_of_their_own():
    built = set(configured_dataclasses()) | group_dataclasses()
    assert {"ngc_gen.app.stages.settings.ReconstructSettings",
            "ngc_gen.data.prepare.PrepareSettings", "ngc_gen.extract.sparse.SparseSettings",
            "ngc_gen.data.autogc.auto.AutoGCSettings", "ngc_gen.data.rigs.rig_gcs.RigGCSettings",
            "ngc_gen.data.autogc.transfer.transfer_settings.TransferSettings"} <= built, \
        sorted(built)
    with_defaults = set()
    for dotted in built | SETTINGS_WITH_DEFAULTS:
        module, _, name = dotted.rpartition(".")
        if defaults(getattr(importlib.import_module(module), name)):
            with_defaults.add(dotted)
    assert with_defaults <= SETTINGS_WITH_DEFAULTS, sorted(with_defaults - SETTINGS_WITH_DEFAULTS)
    assert with_defaults == SETTINGS_WITH_DEFAULTS, \
        f"done: take {sorted(SETTINGS_WITH_DEFAULTS - with_defaults)} off the list"
