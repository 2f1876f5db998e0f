"""Training progress a person can read: steps, not epochs (the stages train for max_steps with
max_epochs = -1, where Lightning's own bar shows `Epoch 0/-2` per epoch).

In a terminal, one bar over the whole run: step / max_steps, the loss and tqdm's rate and ETA.
When stdout is not a terminal (a batch job, a log file), a line every `line_interval_s`
seconds and at the end:

    fit: step 1200/3000  loss 0.01234  41.2 it/s  ETA 0:00:44

it/s and the ETA are the speed measured since the previous line (the first line: since the
first step ended, so start-up, JIT compilation and data loading do not count), not the average
over the run: when other jobs take cores midway the next line's ETA says so, and a slow first
step does not make a 4-minute fit read as 17.
Configured as the `progress` callback (conf/callbacks/default.yaml); rank 0 prints only.
"""
from __future__ import annotations

import sys
import time

from lightning.pytorch.callbacks import ProgressBar


def eta_text(seconds: float) -> str:
    """H:MM:SS of a non-negative number of seconds ('?' when unknown)."""
    if not seconds >= 0 or seconds == float("inf"):
        return "?"
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class StepProgress(ProgressBar):
    """A bar (terminal) or periodic lines (not a terminal) of the optimizer steps of a run.

    refresh_rate: redraw the bar every this many steps; line_interval_s: seconds between lines
    when stdout is not a terminal; metric: the logged value shown as `loss`; desc: the bar's
    label (the stage); terminal: force the bar (True) or the lines (False), None =
    sys.stdout.isatty(). Defaults are conf/callbacks/default.yaml's."""

    def __init__(self, refresh_rate: int = 1, line_interval_s: float = 30.0,
                 metric: str = "train/loss", desc: str = "train", terminal: bool | None = None):
        super().__init__()
        self.refresh_rate, self.line_interval_s = max(1, int(refresh_rate)), float(line_interval_s)
        self.metric, self.desc, self.terminal = metric, str(desc), terminal
        self._enabled = True
        self._bar = None
        self._t0 = self._last = 0.0
        self._start = 0
        self._mark: tuple[int, float] | None = None  # (step, time) the speed is measured from

    # -- ProgressBar's interface ----------------------------------------------------------------
    def disable(self) -> None:
        self._enabled = False

    def enable(self) -> None:
        self._enabled = True

    @property
    def is_enabled(self) -> bool:
        return self._enabled

    def print(self, *args, **kwargs) -> None:
        if self._bar is not None:
            self._bar.write(" ".join(map(str, args)))
        else:
            print(*args, **kwargs)

    # -- what is shown ----------------------------------------------------------------------------
    def _total(self, trainer) -> int | None:
        steps = trainer.max_steps
        return int(steps) if steps is not None and steps > 0 else None

    def _loss(self, trainer) -> float | None:
        value = trainer.progress_bar_metrics.get(self.metric)
        return None if value is None else float(value)

    def line(self, step: int, total: int | None, loss: float | None, now: float) -> str:
        """One progress line: step / total, loss, it/s since the last line (or the first
        step's end), ETA at that speed; the next line measures from here."""
        mark_step, mark_t = self._mark if self._mark is not None else (self._start, self._t0)
        done = step - mark_step
        rate = done / (now - mark_t) if now > mark_t and done > 0 else 0.0
        if done > 0:
            self._mark = (step, now)
        parts = [f"{self.desc}: step {step}/{total if total is not None else '?'}"]
        if loss is not None:
            parts.append(f"loss {loss:.4g}")
        parts.append(f"{rate:.1f} it/s")
        if total is not None:
            parts.append(f"ETA {eta_text((total - step) / rate if rate > 0 else float('inf'))}")
        return "  ".join(parts)

    # -- hooks ------------------------------------------------------------------------------------
    def on_train_start(self, trainer, pl_module) -> None:
        if not self._enabled:
            return
        self._start = int(trainer.global_step)  # a resumed run starts at its checkpoint's step
        self._t0 = self._last = time.perf_counter()
        self._mark = None
        terminal = sys.stdout.isatty() if self.terminal is None else self.terminal
        if terminal:
            from tqdm.auto import tqdm

            self._bar = tqdm(total=self._total(trainer), initial=self._start, unit="step",
                             desc=self.desc, dynamic_ncols=True,
                             file=sys.stdout, smoothing=0.05)

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if not self._enabled:
            return
        step, loss = int(trainer.global_step), self._loss(trainer)
        if self._bar is not None:
            if step % self.refresh_rate == 0 or step == self._bar.total:
                self._bar.n = step
                if loss is not None:
                    self._bar.set_postfix(loss=f"{loss:.4g}", refresh=False)
                self._bar.refresh()
            return
        now = time.perf_counter()
        if self._mark is None:  # the first step is done: measure the speed from here
            self._mark = (step, now)
        if now - self._last >= self.line_interval_s:
            self._last = now
            print(self.line(step, self._total(trainer), loss, now), flush=True)

    def on_train_end(self, trainer, pl_module) -> None:
        if not self._enabled:
            return
        if self._bar is not None:
            self._bar.n = int(trainer.global_step)
            self._bar.close()
            self._bar = None
        else:
            print(self.line(int(trainer.global_step), self._total(trainer),
                            self._loss(trainer), time.perf_counter()), flush=True)
