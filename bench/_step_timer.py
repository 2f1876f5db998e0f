"""A Lightning callback that records when every optimizer step ends: bench/ddp.py adds it to
its training runs (`+callbacks.timer._target_=bench._step_timer.StepTimer`). Its own module, so
that the bench's module imports only the standard library."""
from __future__ import annotations

import json
import time
from pathlib import Path

from lightning.pytorch.callbacks import Callback


class StepTimer(Callback):
    """Writes <out_dir>/rank<r>.json: the perf_counter time after every optimizer step."""

    def __init__(self, out_dir: str):
        self.out_dir, self.times = Path(out_dir), []

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        self.times.append(time.perf_counter())

    def on_train_end(self, trainer, pl_module) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        (self.out_dir / f"rank{trainer.global_rank}.json").write_text(
            json.dumps({"times": self.times, "world_size": trainer.world_size}))
