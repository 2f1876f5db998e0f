"""A Lightning callback for multi-process tests, added to a run from the command line:
`+callbacks.dump._target_=tests.app.rank_dump.RankDump +callbacks.dump.out_dir=<dir>`. When
training ends, every rank writes <out_dir>/rank<r>.pt: its weights, the code ids of the batches it
trained on, its weights when training started, its step and the world size."""
from pathlib import Path

import torch
from lightning.pytorch.callbacks import Callback


class RankDump(Callback):
    def __init__(self, out_dir: str):
        self.out_dir = Path(out_dir)
        self.ids: list[list[int]] = []
        self.start: dict = {}

    def on_train_start(self, trainer, pl_module) -> None:
        self.start = {k: v.detach().cpu().clone() for k, v in pl_module.state_dict().items()}

    def on_train_batch_start(self, trainer, pl_module, batch, batch_idx) -> None:
        first = batch[0] if isinstance(batch, (list, tuple)) else batch
        self.ids.append(first.flatten()[:64].tolist())

    def on_train_end(self, trainer, pl_module) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        state = {k: v.detach().cpu().clone() for k, v in pl_module.state_dict().items()}
        torch.save({"state_dict": state, "ids": self.ids, "start": self.start,
                    "step": int(trainer.global_step), "world_size": int(trainer.world_size)},
                   self.out_dir / f"rank{trainer.global_rank}.pt")
