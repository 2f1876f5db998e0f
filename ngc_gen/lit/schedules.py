"""Learning-rate schedules of the auto-decoder: each multiplies every group's base lr by a factor
of the optimizer step. conf/model's `scheduler` names one (`_partial_: true`); the module adds
the optimiser and the run's length: `scheduler(optimizer, total_steps=trainer.max_steps)`, and
Lightning steps it after every optimizer step.
"""
from __future__ import annotations

import math

from torch.optim import Optimizer
from torch.optim.lr_scheduler import LambdaLR


class StepDecay(LambdaLR):
    """lr x factor^floor(step / (interval x total_steps)). DeepSDF's own schedule halves both
    learning rates every 500 of its 2000 epochs: interval 0.25, factor 0.5."""

    def __init__(self, optimizer: Optimizer, total_steps: int, interval: float = 0.25,
                 factor: float = 0.5):
        self.total_steps, self.interval, self.factor = int(total_steps), interval, factor
        every = max(1, round(interval * total_steps))
        super().__init__(optimizer, lambda step: factor ** (step // every))


class WarmupCosine(LambdaLR):
    """Linear warm-up from 0 over the first `warmup` x total_steps, then a cosine from 1 down
    to `final` at total_steps (and `final` after it)."""

    def __init__(self, optimizer: Optimizer, total_steps: int, warmup: float = 0.02,
                 final: float = 0.1):
        self.total_steps, self.warmup, self.final = int(total_steps), warmup, final
        n_warm = max(1, round(warmup * total_steps)) if warmup > 0 else 0
        total = max(int(total_steps), n_warm + 1)

        def factor(step: int) -> float:
            if step < n_warm:
                return (step + 1) / n_warm
            x = min(1.0, (step - n_warm) / (total - n_warm))
            return final + (1.0 - final) * 0.5 * (1.0 + math.cos(math.pi * x))

        super().__init__(optimizer, factor)
