"""The run directory's file names have one home, `ngc_gen.workspace`: no module of the package
spells one itself, and the configs that name a run's folders agree with it."""
import ast
from pathlib import Path

from ngc_gen import workspace

from .helpers import ROOT, compose_config

# the file names (the folders' names, "meshes" and "checkpoints", are ordinary words too)
NAMES = {workspace.CONFIG, workspace.SEEDS, workspace.LAST, workspace.METRICS, workspace.LATENTS,
         workspace.SHAPES_CHECKPOINT, workspace.SUMMARY, workspace.CONDITION, workspace.EDITED,
         workspace.DEFORMED, workspace.UNDEFORMED, workspace.PROGRAM, workspace.LOCK,
         *workspace.PICTURES.values()}


def spelled_names(path: Path) -> list[str]:
    """`file:line: name` for every string literal of `path` that is a run file's name (the
    docstrings aside)."""
    tree = ast.parse(path.read_text())
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                    ast.AsyncFunctionDef))
                  and n.body and isinstance(n.body[0], ast.Expr)
                  and isinstance(n.body[0].value, ast.Constant)}
    return [f"{path.relative_to(ROOT)}:{n.lineno}: {n.value}" for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in NAMES
            and id(n) not in docstrings]


def test_no_module_spells_a_run_file_name():
    found = [hit for p in sorted((ROOT / "ngc_gen").rglob("*.py"))
             if p.name != "workspace.py" for hit in spelled_names(p)]
    assert not found, "use ngc_gen.workspace's getters: " + "; ".join(found)


def test_the_check_finds_a_spelled_name(tmp_path):
    bad = ROOT / "ngc_gen" / "_spelled_probe.py"
    try:
        bad.write_text('"""doc: metrics.json"""\nPATH = "metrics.json"\n')
        assert spelled_names(bad) == ["ngc_gen/_spelled_probe.py:2: metrics.json"]
    finally:
        bad.unlink()


def test_lightning_writes_the_checkpoints_the_workspace_names():
    from lightning.pytorch.callbacks import ModelCheckpoint

    cfg = compose_config(overrides=["run_dir=/runs/a"])
    node = cfg.callbacks.checkpoint
    assert Path(node.dirpath) == workspace.checkpoints("/runs/a")
    assert node.save_last and ModelCheckpoint.CHECKPOINT_NAME_LAST + \
        ModelCheckpoint.FILE_EXTENSION == workspace.LAST
