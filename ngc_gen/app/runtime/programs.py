"""Edit programs as edit.py and the editor read them: a shipped program (Hydra group `edit`,
package data) or any YAML file, its structure checked before torch loads."""
from __future__ import annotations

from pathlib import Path

import yaml

from ngc_gen.edit.errors import EditError
from ngc_gen.edit.spec import check_program
from ngc_gen.values import load_yaml

PROGRAMS = "ngc_gen/conf/edit"  # the shipped programs: package data, Hydra group `edit`


def available_programs() -> list[str]:
    """Names of the shipped edit programs (found in the installed package, not the checkout)."""
    import importlib.resources

    folder = importlib.resources.files("ngc_gen.conf").joinpath("edit")
    return sorted(f.name[:-5] for f in folder.iterdir() if f.name.endswith(".yaml"))


def load_program_file(path) -> dict:
    """A program read from a YAML file, its structure checked (`spec.check_program`: parts
    and the source); EditError naming the file if it is not one."""
    path = Path(path)
    if not path.is_file():
        raise EditError("program file not found", program=str(path),
                        fix=f"give an existing YAML file, or edit=<name> with one of "
                            f"{available_programs()}")
    try:
        d = load_yaml(path.read_text(encoding="utf-8"))  # 1e-3 a number, no key twice
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or " ".join(str(e).split())
        raise EditError(f"malformed YAML{where}: {problem}", program=str(path),
                        fix="correct the YAML syntax there (indentation, brackets, "
                            "'key: value')") from None
    return {**check_program(d, source=str(path)), "source": str(path)}


def program_from_config(cfg) -> dict:
    """The program of an edit config, its structure checked (the parts of an EditProgram):
    `edit` (a shipped program composed by Hydra) or `program_file` (any YAML path); exactly
    one of them."""
    from omegaconf import OmegaConf

    file, composed = cfg.get("program_file"), cfg.get("edit")
    if (file is None) == (composed is None):
        raise EditError("give exactly one program: edit=<name> (one of "
                        f"{available_programs()}) or program_file=<path.yaml>"
                        + (" (got both)" if file is not None else ""))
    if file is not None:
        return load_program_file(file)
    source = PROGRAMS + "/<edit>.yaml"
    try:
        from hydra.core.hydra_config import HydraConfig

        choice = HydraConfig.get().runtime.choices.get("edit")
        if choice:  # None when composed inside another app (the pipeline stage)
            source = f"{PROGRAMS}/{choice}.yaml"
    except ValueError:  # composed outside @hydra.main (tests, notebooks)
        pass
    return {**check_program(OmegaConf.to_container(composed, resolve=True), source=source),
            "source": source}
