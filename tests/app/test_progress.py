"""Progress a person can read: one bar of step / max_steps with the loss and an ETA in a
terminal, a line at a fixed interval otherwise (a batch job's log), and no warning about the
logging interval on every fit."""
import warnings

import lightning as L
import torch
from torch.utils.data import DataLoader, TensorDataset

from ngc_gen.app.runtime import progress
from ngc_gen.app.runtime.progress import StepProgress, eta_text
from ngc_gen.app.runtime.training import build_trainer

from ..helpers import compose_config


class FakeTrainer:
    def __init__(self, step=0, max_steps=100, loss=0.5):
        self.global_step, self.max_steps = step, max_steps
        self.progress_bar_metrics = {"train/loss": loss}


def test_lines_at_a_fixed_interval_when_not_a_terminal(monkeypatch, capsys):
    clock = iter([0.0, 10.0, 20.0, 31.0, 40.0, 62.0, 70.0])
    monkeypatch.setattr(progress.time, "perf_counter", lambda: next(clock))
    bar = StepProgress(line_interval_s=30.0, desc="fit", terminal=False)
    trainer = FakeTrainer(step=40)  # a resumed run: it/s and ETA count from its first step
    bar.on_train_start(trainer, None)  # t = 0
    for step, loss in ((50, 0.4), (60, 0.3), (70, 0.2), (80, 0.1), (90, 0.05)):
        trainer.global_step, trainer.progress_bar_metrics = step, {"train/loss": loss}
        bar.on_train_batch_end(trainer, None, None, None, 0)  # t = 10, 20, 31, 40, 62
    trainer.global_step = 100
    bar.on_train_end(trainer, None)  # t = 70
    lines = capsys.readouterr().out.splitlines()
    assert lines == [  # the speed since the first step's end (50 at t = 10), then since the last line
        "fit: step 70/100  loss 0.2  1.0 it/s  ETA 0:00:32",   # 20 steps in 21 s
        "fit: step 90/100  loss 0.05  0.6 it/s  ETA 0:00:16",  # 20 steps in 31 s: slower now
        "fit: step 100/100  loss 0.05  1.2 it/s  ETA 0:00:00",  # and at the end
    ]


def test_the_eta_is_the_measured_speed_not_the_start_up(monkeypatch, capsys):
    """A first step that takes 20 s (data, JIT) and then 1 step/s: the first line (t = 30 s,
    step 11) says 1 step/s and 89 s for the 89 steps left (the run's average, 11 steps in
    30 s, would have said 4 minutes)."""
    times = [0.0, 20.0] + [20.0 + k for k in range(1, 32)]
    clock = iter(times)
    monkeypatch.setattr(progress.time, "perf_counter", lambda: next(clock))
    bar = StepProgress(line_interval_s=30.0, desc="fit", terminal=False)
    trainer = FakeTrainer(step=0)
    bar.on_train_start(trainer, None)
    for step in range(1, 33):
        trainer.global_step = step
        bar.on_train_batch_end(trainer, None, None, None, 0)
    assert capsys.readouterr().out.splitlines() == [
        "fit: step 11/100  loss 0.5  1.0 it/s  ETA 0:01:29"]


def test_eta_text():
    assert eta_text(3725.4) == "1:02:05" and eta_text(float("inf")) == "?"


def test_the_bar_counts_steps_to_max_steps(capsys):
    bar = StepProgress(desc="fit", terminal=True)
    trainer = FakeTrainer(step=0, max_steps=20)
    bar.on_train_start(trainer, None)
    for step in range(1, 21):
        trainer.global_step = step
        bar.on_train_batch_end(trainer, None, None, None, 0)
    assert bar._bar.n == 20 and bar._bar.total == 20
    bar.on_train_end(trainer, None)
    out = capsys.readouterr().out
    assert "fit" in out and "20/20" in out and "loss=0.5" in out and "Epoch" not in out


class Tiny(L.LightningModule):
    def __init__(self):
        super().__init__()
        self.w = torch.nn.Linear(2, 1)

    def training_step(self, batch, batch_idx):
        loss = self.w(batch[0]).pow(2).mean()
        self.log("train/loss", loss, prog_bar=True)
        return loss

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.1)


def test_a_fit_shows_steps_and_does_not_warn_about_the_logging_interval(tmp_path, capsys):
    cfg = compose_config(overrides=["stage=fit", f"run_dir={tmp_path}", "trainer.max_steps=6",
                                    "trainer.log_every_n_steps=25", "logger=csv"])
    trainer = build_trainer(cfg, tmp_path)
    assert isinstance(trainer.progress_bar_callback, StepProgress)
    data = DataLoader(TensorDataset(torch.randn(4, 2)), batch_size=2)  # 2 batches an epoch
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        build_trainer(cfg, tmp_path)  # installs the project's filters again, inside this block
        trainer.fit(Tiny(), data)
    assert not [w for w in caught if "logging interval" in str(w.message)]
    assert trainer.global_step == 6
    assert "Epoch 0/-2" not in capsys.readouterr().out
