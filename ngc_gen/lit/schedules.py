"""Learning-rate schedules of the auto-decoder: each multiplies every group's base lr by a factor
of the optimizer step. conf/model's `scheduler` names one (`_partial_: true`); the module adds
the optimiser and the run's length: `scheduler(optimizer, total_steps=trainer.max_steps)`, and
Lightning steps it after every optimizer step.
"""
from __future__ import annotations

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
