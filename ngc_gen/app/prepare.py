"""Stage `prepare`: every shape of the dataset -> cached samples; prints coverage and counts."""
from __future__ import annotations

import time
from pathlib import Path

import hydra
from omegaconf import DictConfig
from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from ngc_gen.data.prepare import PrepareSettings, PreparedShape, prepare_shape

from .cli import torch_threads
from .training import instantiate_group


def settings_from_config(cfg: DictConfig) -> PrepareSettings:
    """The `prepare` group's PrepareSettings (`_target_`; cache_dir is the stage's own)."""
    return instantiate_group(cfg.prepare, ("cache_dir",))


def prepare_dataset(cfg: DictConfig, verbose: bool = True) -> list[PreparedShape]:
    dataset = hydra.utils.instantiate(cfg.data)
    # a dataset built on first use (the procedural creatures) evaluates small grid blocks: one
    # torch thread, since two contend on a busy 2-core machine (0.8 s vs 9 s per shape, measured)
    with torch_threads(1):
        annotations = dataset.shapes()
    settings = settings_from_config(cfg)
    cache_dir = Path(cfg.prepare.cache_dir)
    out, rows = [], []
    bar = tqdm(annotations, desc=f"prepare {dataset.name}", unit="shape",
               disable=not verbose or len(annotations) < 2)
    with logging_redirect_tqdm():  # per-shape log lines above the bar, not through it
        for ann in bar:
            t0 = time.perf_counter()
            shape = prepare_shape(ann, settings, cache_dir)
            out.append(shape)
            rows.append((shape.name, len(shape.gc_names), shape.coverage, len(shape.points),
                         len(shape.pair_point), "cache" if shape.from_cache else
                         f"{time.perf_counter() - t0:.2f} s"))
    if verbose:
        print(f"\n{'shape':24s} {'GCs':>4s} {'coverage':>9s} {'samples':>8s} {'pairs':>8s}  source")
        for name, g, cov, n, p, src in rows:
            print(f"{name:24s} {g:4d} {100 * cov:8.3f}% {n:8d} {p:8d}  {src}")
        for shape in out:
            print(f"{shape.name}: GCs {', '.join(shape.gc_names)}")
        print(f"cache: {cache_dir}")
    return out
