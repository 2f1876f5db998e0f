"""The `next:` line a stage prints: the command that continues the same recipe.

A run of `train.py experiment=collection data=folder data.path=DIR stage=shape_latent` must
suggest `train.py experiment=collection data=folder data.path=DIR stage=diffusion
shape_latent_run=<run>`, not `train.py stage=diffusion ...`: without the experiment and the data
the next stage composes another recipe (and writes under another dataset's name). So the hint
repeats every override the command line gave, except the ones that name this run or its stage,
and adds the links to this run.
"""
from __future__ import annotations

import shlex
from contextlib import contextmanager

# overrides that belong to this run, not to the recipe: the next command gets its own
RUN_KEYS = {"stage", "run_dir", "out_dir", "shape_latent_run", "run", "ckpt_path", "resume",
            "pipeline"}
# sample.py reads the recipe from the run; of train.py's overrides only these apply to it
SAMPLE_KEYS = {"threads", "extract", "viz", "paths"}

_given: list[str] | None = None


@contextmanager
def overrides_used(overrides: list[str]):
    """Within the block, the hint takes `overrides` as the command's (a pipeline step, which is
    composed from Python and has no command line of its own)."""
    global _given
    before, _given = _given, list(overrides)
    try:
        yield
    finally:
        _given = before


def command_overrides() -> list[str]:
    """The overrides of the running command: a pipeline step's, else Hydra's record of the
    command line, else none (a stage called from Python)."""
    if _given is not None:
        return list(_given)
    try:
        from hydra.core.hydra_config import HydraConfig

        return list(HydraConfig.get().overrides.task)
    except (ImportError, ValueError):  # not inside a Hydra job
        return []


def _key(override: str) -> str:
    return override.split("=", 1)[0].lstrip("+~")


def recipe_overrides(overrides: list[str], keep: set[str] | None = None,
                     drop: tuple[str, ...] = ()) -> list[str]:
    """`overrides` without the ones naming this run (RUN_KEYS, hydra.*) or a key in `drop`
    (the key itself and the keys under it); with `keep`, only those whose top key is in it."""
    out = []
    for o in overrides:
        key = _key(o)
        top = key.split(".", 1)[0]
        if top in RUN_KEYS or top == "hydra" or (keep is not None and top not in keep) \
                or any(key == d or key.startswith(d + ".") for d in drop):
            continue
        out.append(o)
    return out


def next_command(entry: str, links: list[str], keep: set[str] | None = None,
                 overrides: list[str] | None = None, drop: tuple[str, ...] = ()) -> str:
    """`python <entry> <recipe overrides> <links>`, each word quoted for a POSIX shell.
    overrides: the command's (default `command_overrides()`); drop: keys that no longer hold
    for the next command (`recipe_overrides`)."""
    given = command_overrides() if overrides is None else overrides
    words = recipe_overrides(given, keep, drop) + list(links)
    return " ".join(["python", entry, *(shlex.quote(w) for w in words)])
