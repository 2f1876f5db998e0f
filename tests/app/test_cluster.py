"""Cluster runs: the SLURM launcher config (hydra/launcher=slurm) composes into the sbatch job a
user expects, trainer=slurm follows it, and preparation sharded over jobs (a multirun over
prepare.shard) writes the same caches as one process, byte for byte."""
import os

import pytest
import trimesh
import yaml
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from omegaconf import OmegaConf

from ngc_gen.app.runtime.config import CONF_DIR, register_resolvers
from ngc_gen.app.runtime.errors import ConfigError
from ngc_gen.app.stages.prepare_data import parse_shard, prepare_dataset

from ..conftest import straight_gc
from ..helpers import compose_config, run_entry

SLURM = ["hydra/launcher=slurm", "trainer=slurm", "stage=fit", "hydra.launcher.partition=gpu",
         "hydra.launcher.nodes=2", "hydra.launcher.gpus_per_node=4",
         "hydra.launcher.timeout_min=90"]


def compose_with_hydra(overrides, tmp_path):
    register_resolvers()
    with initialize_config_dir(version_base="1.3", config_dir=str(CONF_DIR)):
        return compose("train", [*overrides, f"hydra.sweep.dir={tmp_path}/sweep"],
                       return_hydra_config=True)


def test_slurm_launcher_composes_to_the_sbatch_job(tmp_path, monkeypatch):
    """The launcher's settings reach sbatch as submitit writes it (no cluster here: a stand-in
    `srun` on PATH lets submitit build its executor; nothing is submitted)."""
    import submitit
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf

    cfg = compose_with_hydra(SLURM, tmp_path)
    launcher = OmegaConf.to_container(cfg.hydra.launcher, resolve=True)
    assert launcher.pop("_target_").endswith("submitit_launcher.SlurmLauncher")
    assert launcher["tasks_per_node"] == 4  # one process per GPU

    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "srun").write_text("#!/bin/sh\nexit 0\n")
    (fake / "srun").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}{os.pathsep}{os.environ['PATH']}")
    # what SlurmLauncher.launch does with the settings before it submits
    base = set(OmegaConf.structured(BaseQueueConf).keys())
    params = {k if k in base else f"slurm_{k}": v for k, v in launcher.items()
              if k not in ("submitit_folder", "max_num_timeout")}
    executor = submitit.AutoExecutor(cluster="slurm", folder=tmp_path / "submitit")
    executor.update_parameters(**params)
    script = executor._executor._make_submission_file_text("python train.py", "uid")
    for line in ("--partition=gpu", "--nodes=2", "--gpus-per-node=4", "--ntasks-per-node=4",
                 "--time=90", "--cpus-per-task=8", "--mem=32GB"):
        assert f"#SBATCH {line}\n" in script, line


def test_cpu_jobs_for_sharded_preparation_compose(tmp_path):
    """The README's SLURM command for preparation shards: CPU jobs, one task each."""
    cfg = compose_with_hydra(["hydra/launcher=slurm", "stage=prepare", "prepare.shard=0/4",
                              "hydra.launcher.gpus_per_node=null",
                              "hydra.launcher.tasks_per_node=1"], tmp_path)
    launcher = OmegaConf.to_container(cfg.hydra.launcher, resolve=True)
    assert launcher["gpus_per_node"] is None and launcher["tasks_per_node"] == 1
    assert parse_shard(cfg.prepare.shard) == (0, 4)


def test_slurm_trainer_takes_nodes_and_gpus_from_the_launcher(tmp_path):
    cfg = compose_with_hydra(SLURM, tmp_path)
    hc = HydraConfig.instance()
    before = hc.cfg
    try:
        hc.set_config(cfg)  # what a launched job has: `${hydra:launcher...}` resolves
        trainer = OmegaConf.to_container(cfg.trainer, resolve=True)
    finally:
        hc.cfg = before
    assert trainer["strategy"] == "ddp" and trainer["accelerator"] == "gpu"
    assert trainer["devices"] == 4 and trainer["num_nodes"] == 2


@pytest.mark.parametrize("shard, ok", [("0/2", (0, 2)), ("1/2", (1, 2)), (None, None),
                                       ("2/2", None), ("1-2", None), ("a/b", None)])
def test_shard_setting(shard, ok):
    if ok is None and shard is not None:
        with pytest.raises(ConfigError, match="prepare.shard"):
            parse_shard(shard)
    else:
        assert parse_shard(shard) == ok


def folder_of_shapes(root, n=3):
    """n small annotated meshes (icospheres of different sizes, one covering GC each)."""
    folder = root / "meshes"
    folder.mkdir()
    for i in range(n):
        name = f"ball{i}"
        trimesh.creation.icosphere(subdivisions=2, radius=1.0 + 0.1 * i).export(
            folder / f"{name}.ply")
        (folder / f"{name}.yaml").write_text(yaml.safe_dump(
            {"name": name, "mesh": f"{name}.ply", "normalize": {"bound": 0.8},
             "gcs": [straight_gc("body", -0.3, 0.3)]}, sort_keys=False))
    return folder


COMMON = ["stage=prepare", "data=folder", "prepare.n_samples=3000",
          "prepare.coverage_samples=3000"]


def prepare_in(folder, cache, *extra):
    return prepare_dataset(compose_config(overrides=[*COMMON, f"data.path={folder}",
                                                     f"prepare.cache_dir={cache}", *extra]),
                           verbose=False)


def assert_same_files(a, b):
    files = sorted(p.name for p in a.iterdir())
    assert files == ["ball0.npz", "ball1.npz", "ball2.npz"]
    assert sorted(p.name for p in b.iterdir()) == files
    for name in files:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_two_shards_write_the_caches_of_one_process(tmp_path):
    folder = folder_of_shapes(tmp_path)
    whole, sharded = tmp_path / "whole", tmp_path / "sharded"
    assert len(prepare_in(folder, whole)) == 3
    first = prepare_in(folder, sharded, "prepare.shard=0/2")
    second = prepare_in(folder, sharded, "prepare.shard=1/2")
    assert [s.name for s in first] == ["ball0", "ball2"] and [s.name for s in second] == ["ball1"]
    assert_same_files(whole, sharded)


@pytest.mark.slow  # the multirun command in a subprocess: `make test-all`
def test_a_multirun_over_shards_writes_the_caches_of_one_process(tmp_path):
    folder = folder_of_shapes(tmp_path)
    whole, sharded = tmp_path / "whole", tmp_path / "sharded"
    prepare_in(folder, whole)
    # the basic launcher runs the jobs one after the other; hydra/launcher=slurm submits them
    r = run_entry("train.py", "-m", *COMMON, f"data.path={folder}",
                  f"prepare.cache_dir={sharded}", "threads=1", "prepare.shard=0/2,1/2",
                  f"hydra.sweep.dir={tmp_path}/sweep")
    assert r.returncode == 0, r.stderr[-3000:]
    assert "shard 0/2: 2 shapes" in r.stdout and "shard 1/2: 1 shapes" in r.stdout
    assert_same_files(whole, sharded)


def test_shard_is_refused_outside_stage_prepare(tmp_path):
    cfg = compose_config(overrides=["stage=fit", "prepare.shard=0/2",
                                    f"prepare.cache_dir={tmp_path}"])
    with pytest.raises(ConfigError, match="sharding is for stage=prepare"):
        prepare_dataset(cfg)
