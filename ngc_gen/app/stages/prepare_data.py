"""Stage `prepare`: every shape of the dataset -> cached samples; prints coverage and counts.

`prepare.shard=i/n` prepares only shapes i, i + n, i + 2n, ... of the dataset, so n jobs (a
multirun over i, e.g. on SLURM) fill the same cache as one process would, file for file."""
from __future__ import annotations

import os
import time

from omegaconf import DictConfig
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from ngc_gen.data.prepare import PrepareSettings, PreparedShape, prepare_shape, prepare_uncached

from ..runtime.cli import torch_threads
from ..runtime.errors import ConfigError
from ..runtime.checks import check_writable
from ..runtime.config import instantiate, instantiate_group

RUNNER_KEYS = ("cache_dir", "shard", "workers")  # settings the stage reads itself (not PrepareSettings)


def settings_from_config(cfg: DictConfig) -> PrepareSettings:
    """The `prepare` group's PrepareSettings (`_target_`; cache_dir and shard are the stage's)."""
    return instantiate_group(cfg.prepare, RUNNER_KEYS)


def parse_shard(shard) -> tuple[int, int] | None:
    """`i/n` -> (i, n) with 0 <= i < n; None for no sharding. ConfigError otherwise."""
    if shard is None:
        return None
    fix = "write prepare.shard=i/n with 0 <= i < n, e.g. prepare.shard=0/4 (the first of 4 jobs)"
    try:
        i, n = (int(x) for x in str(shard).split("/"))
    except ValueError:
        raise ConfigError("is not of the form i/n", key="prepare.shard", value=shard,
                          fix=fix) from None
    if not 0 <= i < n:
        raise ConfigError("needs 0 <= i < n", key="prepare.shard", value=shard, fix=fix)
    return i, n


def process_rank() -> int:
    """This process's rank in a multi-process run (0 when alone): the variables torchrun,
    Lightning's launcher and SLURM set, in Lightning's order."""
    for key in ("RANK", "LOCAL_RANK", "SLURM_PROCID"):
        if os.environ.get(key, "").isdigit():
            return int(os.environ[key])
    return 0


def prepare_dataset(cfg: DictConfig, verbose: bool = True,
                    check_annotations=None) -> list[PreparedShape]:
    """The dataset's shapes, prepared (from the cache when it is up to date); the table of
    shapes is printed by rank 0 only. `check_annotations(annotations)`: a stage's own check of
    the dataset's annotations, run before any shape is prepared (shape_latent: one GC layout)."""
    verbose = verbose and process_rank() == 0
    shard = parse_shard(cfg.prepare.get("shard"))
    if shard is not None and cfg.get("stage", "prepare") != "prepare":
        raise ConfigError(f"sharding is for stage=prepare; stage={cfg.stage} needs every shape",
                          key="prepare.shard", value=cfg.prepare.shard,
                          fix="prepare in shards first (stage=prepare prepare.shard=i/n), then "
                              "train without prepare.shard: it reads the filled cache")
    cache_dir = check_writable(cfg.prepare.cache_dir, "prepare.cache_dir")
    settings = settings_from_config(cfg)
    dataset = instantiate(cfg.data, "data")
    # a dataset built on first use (the procedural creatures) evaluates small grid blocks: one
    # torch thread, since two contend on a busy 2-core machine (0.8 s vs 9 s per shape, measured)
    with torch_threads(1):
        annotations = dataset.shapes()
    if check_annotations is not None:
        check_annotations(annotations)
    if shard is not None:
        annotations = annotations[shard[0]::shard[1]]
    # shapes not in the cache: made in worker processes first (about a second each), then read
    made = prepare_uncached(annotations, settings, cache_dir, workers=cfg.prepare.workers)
    out, rows = [], []
    bar = tqdm(annotations, desc=f"prepare {dataset.name}", unit="shape",
               disable=not verbose or len(annotations) < 2)
    with logging_redirect_tqdm():  # per-shape log lines above the bar, not through it
        for ann in bar:
            t0 = time.perf_counter()
            shape = prepare_shape(ann, settings, cache_dir)
            out.append(shape)
            seconds = made.get(shape.name, None if shape.from_cache else time.perf_counter() - t0)
            rows.append((shape.name, len(shape.gc_names), shape.coverage, len(shape.points),
                         len(shape.pair_point), "cache" if seconds is None else f"{seconds:.2f} s"))
    if verbose:
        print(f"\n{'shape':24s} {'GCs':>4s} {'coverage':>9s} {'samples':>8s} {'pairs':>8s}  source")
        for name, g, cov, n, p, src in rows:
            print(f"{name:24s} {g:4d} {100 * cov:8.3f}% {n:8d} {p:8d}  {src}")
        for shape in out:
            print(f"{shape.name}: GCs {', '.join(shape.gc_names)}")
        print(f"cache: {cache_dir}" + (f" (shard {shard[0]}/{shard[1]}: {len(out)} shapes)"
                                        if shard is not None else ""))
    return out
