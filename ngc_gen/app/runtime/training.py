"""What the training stages share: the run directory, the module of a config group, and a
Lightning trainer built from the config (callbacks, logger, quiet console, resume, several
processes)."""
from __future__ import annotations

import json
import logging
import re
import time
from pathlib import Path
from typing import NamedTuple

from lightning.pytorch.callbacks import Callback
from omegaconf import DictConfig, OmegaConf

from ngc_gen import workspace
from ngc_gen.data.atomic import atomic_write_text

from .checks import trainer_steps
from .config import instantiate

SEED_KEY = re.compile(r"(^|_)seed$")


def config_seeds(cfg: DictConfig) -> dict:
    """Every seed setting of the config, by its dotted key (seed, prepare.seed, data.seed,
    metrics_seed, ...)."""
    out = {}

    def walk(node, prefix: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                key = f"{prefix}{k}"
                if SEED_KEY.search(str(k)) and (v is None or isinstance(v, int)):
                    out[key] = v
                walk(v, f"{key}.")
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, f"{prefix}{i}.")

    walk(OmegaConf.to_container(cfg, resolve=True), "")
    return out


def start_run(cfg: DictConfig, fixed_seeds: dict | None = None) -> Path:
    """Create the run directory and record the resolved config in it first, and every seed the
    run uses in seeds.json: the config's seed settings, the stage's `fixed_seeds` (evaluation
    seeds that are constants of the stage) and how ranks of a multi-process run seed."""
    trainer_steps(cfg)  # a malformed trainer setting fails before the run directory is made
    run_dir = Path(cfg.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(workspace.config(run_dir), OmegaConf.to_yaml(cfg, resolve=True))
    seeds = {"config": config_seeds(cfg), "fixed": dict(fixed_seeds or {}),
             "ranks": "rank r of a multi-process run reseeds with seed + r when training starts"
                      " (its own noise); one process keeps seed"}
    atomic_write_text(workspace.seeds(run_dir), json.dumps(seeds, indent=2))
    return run_dir


class _DropTip(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return "litlogger" not in record.getMessage()


def quiet_lightning() -> None:
    """One copy of each Lightning message: under Hydra the root handler already prints it (and
    writes it to <run>/<job>.log), so Lightning's own console handler only repeats it. Its
    advertising tip and a deprecation warning it raises inside itself (torch's LeafSpec) say
    nothing about the run and are dropped too."""
    import warnings

    import lightning  # noqa: F401  (installs its handler, which is then removed)

    if logging.getLogger().hasHandlers():
        lg = logging.getLogger("lightning")
        for h in [h for h in lg.handlers if type(h) is logging.StreamHandler]:
            lg.removeHandler(h)
    tip = logging.getLogger("lightning.pytorch.utilities.rank_zero")
    if not any(isinstance(f, _DropTip) for f in tip.filters):
        tip.addFilter(_DropTip())
    warnings.filterwarnings("ignore", message=r".*isinstance\(treespec, LeafSpec\)")
    # the stages train for max_steps over short epochs; logging counts steps across epochs,
    # so an epoch shorter than log_every_n_steps loses no log line (Lightning warns anyway)
    warnings.filterwarnings("ignore", message=r".*smaller than the logging interval")
    # resuming (ngc_gen.app.runtime.resume): the run directory's logs and checkpoints are continued on
    # purpose, and the interrupted epoch's batches are drawn again (docs/scaling.md)
    for message in (r"Experiment logs directory .* exists and is not empty",
                    r"Checkpoint directory .* exists and is not empty",
                    r"You're resuming from a checkpoint that ended before the epoch ended"):
        warnings.filterwarnings("ignore", message=message)


def build_callbacks(cfg: DictConfig) -> list:
    """The Lightning callbacks of `cfg.callbacks` (an entry set to null is dropped).
    `every_n_train_steps: null` means trainer.max_steps / 4, at most 500; the progress bar is
    dropped when trainer.enable_progress_bar is false (Lightning refuses both at once)."""
    from lightning.pytorch.callbacks import ProgressBar

    out = []
    for node in (cfg.get("callbacks") or {}).values():
        if node is None:
            continue
        kw = {}
        if "every_n_train_steps" in node and node.every_n_train_steps is None:
            kw["every_n_train_steps"] = max(1, min(500, trainer_steps(cfg) // 4))
        cb = instantiate(node, "callbacks", **kw)
        if isinstance(cb, ProgressBar) and not cfg.trainer.get("enable_progress_bar", True):
            continue
        out.append(cb)
    return out


class RankSeeds(Callback):
    """In a multi-process run, rank r reseeds with seed + r when training starts, so ranks draw
    their own noise (EDM noise levels, latent noise) for their own batches; one process keeps
    the seed it has (single-process runs are unchanged)."""

    def __init__(self, seed: int):
        self.seed = int(seed)

    def on_train_start(self, trainer, pl_module) -> None:
        if trainer.world_size > 1:
            import lightning as L

            L.seed_everything(self.seed + trainer.global_rank, workers=True, verbose=False)


class StartStep(Callback):
    """Records the optimizer step training starts from (the checkpoint's when resuming)."""

    step: int | None = None

    def on_train_start(self, trainer, pl_module) -> None:
        self.step = int(trainer.global_step)


class TrainClock(Callback):
    """Training wall time summed over resumed segments (it travels in the checkpoints), a row
    (step, seconds, loss) every `every` steps in <dirpath>/clock.csv, and a checkpoint
    <dirpath>/at_<s>s.ckpt the first time the total passes each of `marks` seconds: a long run
    can be scored at the wall time of a shorter one."""

    def __init__(self, dirpath: str, marks=(), every: int = 25, metric: str = "train/loss"):
        self.dirpath, self.marks = Path(dirpath), sorted(float(m) for m in marks)
        self.every, self.metric = max(1, int(every)), metric
        self.base, self.done = 0.0, []
        self._t0 = None

    @property
    def seconds(self) -> float:
        return self.base + (time.perf_counter() - self._t0 if self._t0 is not None else 0.0)

    def state_dict(self) -> dict:
        return {"seconds": self.seconds, "done": list(self.done)}

    def load_state_dict(self, state: dict) -> None:
        self.base, self.done = float(state["seconds"]), list(state["done"])

    def on_train_start(self, trainer, pl_module) -> None:
        self._t0 = time.perf_counter()

    def on_train_end(self, trainer, pl_module) -> None:
        self.base, self._t0 = self.seconds, None

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if not trainer.is_global_zero:
            return
        step, t = int(trainer.global_step), self.seconds
        if step % self.every == 0:
            loss = trainer.callback_metrics.get(self.metric)
            self.dirpath.mkdir(parents=True, exist_ok=True)
            with open(self.dirpath / "clock.csv", "a") as f:
                f.write(f"{step},{t:.2f},{float(loss) if loss is not None else float('nan'):.6g}\n")
        for m in self.marks:
            if t >= m and m not in self.done:
                self.done.append(m)
                trainer.save_checkpoint(self.dirpath / f"at_{m:g}s.ckpt")


def build_trainer(cfg: DictConfig, run_dir: Path, extra_callbacks=(), resume_step: int = 0):
    """The Lightning trainer of `cfg.trainer` with `cfg.callbacks` and `cfg.logger`;
    checkpoints are written atomically, and a resumed run's CSV log keeps its earlier rows."""
    from .resume import AtomicCheckpointIO

    quiet_lightning()
    logger = instantiate(cfg.logger, "logger") if cfg.get("logger") else False
    if hasattr(logger, "keep_until"):
        logger.keep_until = int(resume_step)
    callbacks = build_callbacks(cfg) + [RankSeeds(cfg.seed)] + list(extra_callbacks)
    return instantiate(cfg.trainer, "trainer", callbacks=callbacks, logger=logger,
                       default_root_dir=str(run_dir), plugins=[AtomicCheckpointIO()])


class Trained(NamedTuple):
    trainer: object
    seconds: float
    start_step: int  # the step training started from: 0, or the resumed checkpoint's step


def train(cfg: DictConfig, run_dir: Path, module, *data, **fit_kwargs) -> Trained:
    """trainer.fit, resuming from the run directory's last.ckpt or `ckpt_path`
    (`resume.resume_point`); (trainer, seconds, start step)."""
    from .resume import resume_point

    point = resume_point(cfg, run_dir, module.hparams.get("checkpoint_kind"))
    start = StartStep()
    trainer = build_trainer(cfg, run_dir, [start], resume_step=point.step)
    if point.path is not None and trainer.is_global_zero:
        print(f"resuming from {point.path} (step {point.step})", flush=True)
    t0 = time.perf_counter()
    try:
        trainer.fit(module, *data, ckpt_path=point.path, **fit_kwargs)
    except RuntimeError as e:
        if point.path is None or "state_dict" not in str(e):
            raise
        from .errors import ConfigError

        first = next((ln.strip() for ln in str(e).splitlines() if "mismatch" in ln
                      or "Missing key" in ln or "Unexpected key" in ln), str(e).splitlines()[0])
        raise ConfigError(f"cannot resume from {point.path}: it holds another model than this "
                          f"config builds ({first.rstrip('.')})",
                          fix="start in a new run directory (hydra.run.dir=...), or resume with "
                              "the model settings the checkpoint was trained with") from None
    return Trained(trainer, time.perf_counter() - t0, start.step)
