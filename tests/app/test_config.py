"""The configs under conf/ are the single source of settings: every option of every config group
composes and builds (`_target_`) into objects that carry the YAML's values, a Python default
equals the base YAML that sets it, and each entry point's --help shows only the groups it reads.
"""
import inspect
from pathlib import Path

import hydra
import pytest
import torch
from omegaconf import OmegaConf

from ngc_gen.app.stages import train_diffusion as diffusion_stage
from ngc_gen.app.stages import prepare_data as prepare_stage
from ngc_gen.app.stages import train_shape_latent as shape_latent_stage
from ngc_gen.app.runtime.programs import available_programs
from ngc_gen.app.stages.prepare_data import settings_from_config
from ngc_gen.app.runtime.config import instantiate_group
from ngc_gen.app.runtime.training import build_callbacks

from ..conftest import straight_gc
from ..helpers import ROOT, compose_config, run_entry

CONF = ROOT / "conf"
# group -> settings the stage reads itself (not arguments of the group's _target_)
RUNNER_KEYS = {"shape_latent": shape_latent_stage.RUNNER_KEYS,
               "diffusion": diffusion_stage.RUNNER_KEYS, "prepare": prepare_stage.RUNNER_KEYS}
BUILT = ("data", "model", "shape_latent", "diffusion", "prepare", "trainer", "logger",
         "callbacks")


def options(group: str) -> list[str]:
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


def yaml_of(group: str, option: str) -> dict:
    """The option's composed node as plain data, interpolations resolved."""
    cfg = compose(group, option)
    return OmegaConf.to_container(cfg[group], resolve=True)


def compose(group: str, option: str, run_dir="/tmp/ngc-config-test"):
    overrides = [f"{group}={option}", f"run_dir={run_dir}"]
    if (group, option) == ("data", "folder"):
        overrides.append("data.path=/any/meshes")
    return compose_config(overrides=overrides)


def plain(v):
    """Comparable form of a built object's attribute: paths as str, tuples as lists."""
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def assert_carries(obj, node: dict, where: str) -> None:
    """Every key of a `_target_` node is an attribute of the built object with the YAML's value
    (nested `_target_` nodes recursively)."""
    assert type(obj) is hydra.utils.get_class(node["_target_"]), where
    for k, v in node.items():
        if k.startswith("_"):
            continue
        got = getattr(obj, k)
        if isinstance(v, dict) and "_target_" in v:
            assert_carries(got, v, f"{where}.{k}")
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for i, (o, n) in enumerate(zip(got, v, strict=True)):
                assert_carries(o, n, f"{where}.{k}[{i}]")
        else:
            assert plain(got) == v, (where, k, got, v)


def tiny_template() -> dict:
    from ngc_gen.models.shape_decoder import GCTemplate

    gcs = [straight_gc("body", -0.3, 0.3), straight_gc("tail", 0.3, 0.6)]
    return GCTemplate.from_gcs(gcs, where="test").to_dict()


def assert_module_carries(module, node: dict, runner: tuple = ()) -> None:
    """A LightningModule built from a group: hyper-parameters, networks and optimiser are the
    YAML's."""
    for k, v in node.items():
        if k.startswith("_") or k in runner:
            continue
        if isinstance(v, dict) and "_target_" in v:
            built = getattr(module, {"optimizer": "make_optimizer",
                                      "scheduler": "make_scheduler"}.get(k, k), None)
            sizes = {kk: vv for kk, vv in v.items() if not kk.startswith("_")}
            if v.get("_partial_"):  # a factory: the recorded keyword arguments are the YAML's
                cls = hydra.utils.get_class(v["_target_"])
                if k in ("optimizer", "scheduler"):
                    assert built.func is cls and plain(built.keywords) == plain(sizes), k
                else:
                    assert module.hparams[k] == sizes, k
            else:  # a built network: its class and sizes
                net = built if built is not None else getattr(module, "ngc")
                assert type(net) is hydra.utils.get_class(v["_target_"]), k
                assert net.config == sizes and module.hparams[k] == sizes, k
        elif k == "scheduler":  # null: constant learning rates
            assert v is None and module.make_scheduler is None
        else:
            assert module.hparams[k] == v, (k, module.hparams[k], v)


@pytest.mark.parametrize("group, option", [(g, o) for g in BUILT for o in options(g)])
def test_every_option_builds_with_the_yaml_values(group, option, tmp_path):
    if (group, option) == ("trainer", "gpu") and not torch.cuda.is_available():
        pytest.skip("trainer=gpu needs a CUDA device")
    if (group, option) == ("trainer", "slurm"):
        pytest.skip("trainer=slurm reads the launched job's hydra.launcher (test_cluster.py)")
    cfg = compose(group, option, tmp_path)
    node = OmegaConf.to_container(cfg[group], resolve=True)
    if group == "data":
        assert_carries(hydra.utils.instantiate(cfg.data), node, f"data={option}")
        name = "meshes" if option == "folder" else option  # a folder: named after itself
        assert cfg.prepare.cache_dir == f"{ROOT}/.cache/prepared/{name}"  # one cache each
    elif group == "model":
        module = instantiate_group(cfg.model, n_codes=3, meta={"shapes": []})
        assert module.codes.weight.shape[0] == 3
        assert_module_carries(module, node)
        if node.get("scheduler"):  # the scheduler the run steps: the YAML's values, its lr factors
            opt = module.make_optimizer([{"params": module.decoder.parameters(), "lr": 1.0},
                                         {"params": module.codes.parameters(), "lr": 2.0}])
            sched = module.make_scheduler(opt, total_steps=100)
            assert_carries(sched, {"total_steps": 100, **node["scheduler"]}, f"model={option}")
            lrs = []
            for _ in range(100):
                lrs.append([g["lr"] for g in opt.param_groups])
                opt.step()
                sched.step()
            if option == "deepsdf":  # halved every quarter of the steps, both groups
                assert lrs[0] == [1.0, 2.0] and lrs[24] == [1.0, 2.0] and lrs[25] == [0.5, 1.0]
                assert lrs[99] == [0.125, 0.25]
    elif group == "shape_latent":
        module = instantiate_group(cfg.shape_latent, RUNNER_KEYS[group], n_shapes=2,
                                   template=tiny_template(), meta={})
        assert module.ngc.config == {k: v for k, v in node["ngc"].items() if k != "_target_"}
        assert_module_carries(module, node, RUNNER_KEYS[group])
    elif group == "diffusion":
        module = instantiate_group(cfg.diffusion, RUNNER_KEYS[group], dim=8)
        assert module.net.model.dim == 8
        assert_module_carries(module, node, RUNNER_KEYS[group])
    elif group == "prepare":
        settings = settings_from_config(cfg)
        runner = ("_target_", *RUNNER_KEYS[group])
        assert {k: getattr(settings, k) for k in node if k not in runner} \
            == {k: v for k, v in node.items() if k not in runner}
    elif group == "trainer":
        trainer = hydra.utils.instantiate(cfg.trainer, logger=False)
        assert trainer.max_steps == node["max_steps"] and trainer.max_epochs == node["max_epochs"]
        assert trainer.log_every_n_steps == node["log_every_n_steps"]
        assert trainer.num_devices == node["devices"]
        assert type(trainer.accelerator).__name__.lower().startswith(node["accelerator"])
        if "strategy" in node:  # ddp: the other ranks run the same command (Hydra-aware)
            assert type(trainer.strategy).__name__ == "DDPStrategy"
            assert trainer.num_nodes == node["num_nodes"]
    elif group == "logger":
        logger = hydra.utils.instantiate(cfg.logger)
        assert type(logger) is hydra.utils.get_class(node["_target_"])
        assert str(logger.save_dir) == str(tmp_path) == node["save_dir"]
        if "offline" in node:  # wandb: `name` is the run's, the logger's .name the project's
            assert logger._offline == node["offline"] and logger.name == node["project"]
            assert logger._wandb_init["name"] == node["name"] == "prepare-ant"
        else:
            assert logger.name == node["name"]
    else:  # callbacks
        built = build_callbacks(cfg)
        assert [type(c) for c in built] == [hydra.utils.get_class(n["_target_"])
                                           for n in node.values()]
        check = built[0]
        assert check.dirpath == str(tmp_path / "checkpoints") == node["checkpoint"]["dirpath"]
        for k in ("filename", "monitor", "mode", "save_top_k", "save_last"):
            assert getattr(check, k) == node["checkpoint"][k], k
        assert check._every_n_train_steps == min(500, cfg.trainer.max_steps // 4)  # null's rule
        assert built[1].refresh_rate == node["progress"]["refresh_rate"]


def test_callbacks_follow_the_trainer_settings(tmp_path):
    cfg = compose_config(overrides=[f"run_dir={tmp_path}", "trainer.max_steps=20",
                                    "trainer.enable_progress_bar=false",
                                    "callbacks.checkpoint.every_n_train_steps=7"])
    built = build_callbacks(cfg)
    assert len(built) == 1 and built[0]._every_n_train_steps == 7  # no progress bar
    cfg = compose_config(overrides=[f"run_dir={tmp_path}", "trainer.max_steps=20",
                                    "callbacks.progress=null"])
    assert len(build_callbacks(cfg)) == 1 and build_callbacks(cfg)[0]._every_n_train_steps == 5


def base_options():
    """(group, option) of the options that derive from no other (no `defaults:`): the YAML a
    Python default must equal. Presets deriving from them (model=paper) change values on
    purpose."""
    out = []
    for group in ("data", "model", "shape_latent", "diffusion", "prepare"):
        for option in options(group):
            if "defaults" not in OmegaConf.load(CONF / group / f"{option}.yaml"):
                out.append((group, option))
    return out


@pytest.mark.parametrize("group, option", base_options())
def test_python_defaults_equal_the_base_yaml(group, option):
    """No Python default differs from the YAML users run: for ngc_gen's own classes, every
    parameter the YAML sets that also has a default in the signature has the YAML's value."""
    def check(node: dict, where: str):
        target = node.get("_target_", "")
        if not target.startswith("ngc_gen."):
            return 0
        params = inspect.signature(hydra.utils.get_class(target)).parameters
        n = 0
        for k, v in node.items():
            if isinstance(v, dict):
                n += check(v, f"{where}.{k}")
            elif k in params and params[k].default is not inspect.Parameter.empty \
                    and k not in RUNNER_KEYS.get(group, ()) and "${" not in str(v):
                assert params[k].default == v, (where, k, params[k].default, v)
                n += 1
        return n

    node = OmegaConf.to_container(OmegaConf.load(CONF / group / f"{option}.yaml"))
    check(node, f"{group}={option}")


def test_model_shape_latent_and_diffusion_options_all_have_a_target():
    for group in ("model", "shape_latent", "diffusion"):
        for option in options(group):
            node = yaml_of(group, option)
            assert node["_target_"].startswith("ngc_gen.lit."), (group, option)


def test_each_entry_point_composes_its_own_groups():
    train = compose_config("train", ["run_dir=x"])
    edit = compose_config("edit", ["edit=bent_tail"])
    sample = compose_config("sample", ["out_dir=x"])
    # one name per setting: the extract group, each entry point with its resolution
    assert (train.extract.resolution, edit.extract.resolution, sample.extract.resolution) == \
        (256, 160, 128)
    assert train.extract.bound == edit.extract.bound == sample.extract.bound == 1.0
    assert sample.extract.chunk is None and edit.extract.chunk == train.extract.chunk
    assert train.viz.up == edit.viz.up == sample.viz.up == "auto"  # one home: conf/viz
    assert not {"data", "model", "trainer", "diffusion", "mode"} & set(edit)
    assert not {"data", "model", "trainer", "diffusion", "edit"} & set(sample)
    assert Path(train.paths.root_dir) == ROOT and edit.edit.name == "bent_tail"
    modes = {m: compose_config("sample", [f"mode={m}", "out_dir=x"]) for m in options("mode")}
    assert set(modes) == {"generate", "interpolate", "mix", "condition", "export"}
    assert modes["export"].export.joints_per_gc == 4 and "n" not in modes["export"]
    assert modes["generate"].n == 16 and "a" not in modes["generate"]
    assert modes["interpolate"].steps == 8 and "part" not in modes["interpolate"]
    assert modes["mix"].part == "head" and "n" not in modes["mix"]
    assert all(c.mode == m for m, c in modes.items())
    for exp in options("experiment"):
        assert compose_config("train", [f"experiment={exp}", "run_dir=x"]).stage in (
            "pipeline", "shape_latent")


@pytest.mark.parametrize("script, groups", [
    ("train.py", {"annotate", "callbacks", "data", "diffusion", "experiment", "extract", "logger",
                  "metrics", "model",
                  "paths", "prepare", "reconstruct", "shape_latent", "trainer", "viz"}),
    ("edit.py", {"edit", "editor", "extract", "viz"}),
    ("sample.py", {"extract", "mode", "viz"}),
])
def test_help_lists_only_the_groups_the_entry_point_reads(script, groups):
    r = run_entry(script, "--help", timeout=120)
    assert r.returncode == 0, r.stderr
    section = r.stdout.split("== Configuration groups (group=option) ==")[1].split("== Config")[0]
    listed = {line.split(":")[0] for line in section.strip().splitlines()}
    assert listed == groups
    if script == "edit.py":
        assert f"edit: {', '.join(available_programs())}" in section


def test_edit_programs_ship_inside_the_package(monkeypatch, tmp_path):
    """The shipped programs are package data (ngc_gen/conf/edit), not files of the checkout: they
    are found with NGC_ROOT pointing elsewhere, and pyproject ships every one of them."""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    monkeypatch.setenv("NGC_ROOT", str(tmp_path))
    names = available_programs()
    assert {"bent_tail", "head_swap", "posed_ant_leg", "scaled_head", "stretched_torso",
            "twisted_leg"} <= set(names)
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())[
        "tool"]["setuptools"]["package-data"]["ngc_gen.conf"]
    shipped = {p.stem for g in globs for p in (ROOT / "ngc_gen/conf").glob(g)}
    assert shipped == set(names)


def test_the_sparse_extraction_settings_come_from_the_extract_group():
    """`extract.sparse` (conf/extract/default.yaml) is where the sparse refinement's defaults
    live: it builds the library's `SparseSettings.from_yaml()`, an override reaches the object
    every stage extracts with, and a bad value or an unknown key is a ConfigError that names
    the key."""
    from ngc_gen.app.runtime.config import sparse_settings
    from ngc_gen.app.runtime.errors import ConfigError
    from ngc_gen.extract import SparseSettings

    for config in ("train", "edit", "sample"):
        cfg = compose_config(config_name=config)
        assert sparse_settings(cfg.extract.sparse) == SparseSettings.from_yaml()
    cfg = compose_config(config_name="edit", overrides=["extract.sparse.track=false",
                                                        "extract.sparse.lipschitz=2.0"])
    assert sparse_settings(cfg.extract.sparse) == SparseSettings.from_yaml(track=False,
                                                                            lipschitz=2.0)
    assert sparse_settings(cfg.editor.sparse) == sparse_settings(cfg.extract.sparse)
    cfg = compose_config(config_name="sample", overrides=["extract.sparse.lipschitz=0.5"])
    with pytest.raises(ConfigError, match=r"extract.sparse.*lipschitz margin must be >= 1"):
        sparse_settings(cfg.extract.sparse)
    cfg = compose_config(config_name="sample", overrides=["+extract.sparse.lipshitz=2.0"])
    with pytest.raises(ConfigError, match=r"extract.sparse.*lipshitz"):
        sparse_settings(cfg.extract.sparse)
