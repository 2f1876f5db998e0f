"""Lightning DataModule over prepared shapes: batches of (code id, coords, sdf), no geometry.

mode="ngc": one row per (sample, containing GC) pair; code id = global GC index, coords =
relative [u, a, b] (computed once at preparation). mode="deepsdf": one row per sample; code id =
shape index, coords = normalised world xyz. Both models read batches the same way. With a
blend width (the blended union, `ngc_gen.geometry.union`) an ngc batch also carries each row's
share of its sample (`blend_shares`), which the loss weighs rows by.
"""
from __future__ import annotations

import lightning as L
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from ngc_gen.data.prepare import PreparedShape


def training_rows(shapes: list[PreparedShape], mode: str):
    """Concatenate shapes into (ids (R,) i64, coords (R, 3) f32, sdf (R,) f32, n_codes)."""
    ids, coords, sdf, offset = [], [], [], 0
    for i, s in enumerate(shapes):
        if mode == "ngc":
            ids.append(s.pair_gc.astype(np.int64) + offset)
            coords.append(s.pair_rel)
            sdf.append(s.sdf[s.pair_point])
            offset += len(s.gc_names)
        elif mode == "deepsdf":
            ids.append(np.full(len(s.points), i, dtype=np.int64))
            coords.append(s.points)
            sdf.append(s.sdf)
            offset += 1
        else:
            raise ValueError(f"mode must be 'ngc' or 'deepsdf', got {mode!r}")
    return (torch.from_numpy(np.concatenate(ids)),
            torch.from_numpy(np.concatenate(coords).astype(np.float32)),
            torch.from_numpy(np.concatenate(sdf).astype(np.float32)), offset)


def blend_shares(shapes: list[PreparedShape], width: float) -> torch.Tensor:
    """(R,) float32 in `training_rows(shapes, "ngc")` order: the row's GC weight in the blended
    union of that width over the sum of the weights of its sample's GCs (1 for a sample one
    GC holds)."""
    from ngc_gen.geometry import GeneralizedCylinder, fade_weight

    out = []
    for s in shapes:
        w = fade_weight(GeneralizedCylinder.relative_measure(s.pair_rel.astype(np.float64)),
                        width)
        total = np.bincount(s.pair_point, weights=w, minlength=len(s.points))
        out.append(w / total[s.pair_point])
    return torch.from_numpy(np.concatenate(out).astype(np.float32))


def shared_rows(shapes: list[PreparedShape]) -> torch.Tensor:
    """(R,) bool in `training_rows(shapes, "ngc")` order: the row's sample is paired with two
    or more GCs (where GCs overlap, or within a pair margin of another GC: a junction)."""
    out = []
    for s in shapes:
        k = np.bincount(s.pair_point, minlength=len(s.points))
        out.append(k[s.pair_point] >= 2)
    return torch.from_numpy(np.concatenate(out))


def row_weights(ids: torch.Tensor, balance: float, shared: torch.Tensor | None = None,
                junction_weight: float = 0.0) -> torch.Tensor | None:
    """Sampling weight per row: `code_balance_weights`, times 1 + junction_weight on `shared`
    rows (samples where GCs meet drawn more often); None when every row is equally likely."""
    w = code_balance_weights(ids, balance)
    if junction_weight == 0 or shared is None:
        return w
    boost = 1.0 + float(junction_weight) * shared.double()
    return boost if w is None else w * boost


def code_balance_weights(ids: torch.Tensor, balance: float) -> torch.Tensor | None:
    """Row weights n_c^-balance, n_c = the rows of the row's code (GC or shape): 0 leaves every
    row equally likely (None), 1 gives every code the same share of a batch, so a thin part
    (few samples) is seen as often as the torso."""
    if balance == 0:
        return None
    counts = torch.bincount(ids).double()
    return counts[ids] ** (-float(balance))


class ShuffledBatches(Dataset):
    """Item i = batch i of this epoch's permutation of all rows (whole batches per item:
    per-row indexing through a DataLoader would dominate the step time on CPU). With row
    `weights`, an epoch draws as many rows with replacement, in proportion to them."""

    def __init__(self, ids, coords, sdf, batch_size: int, seed: int = 0, weights=None,
                 shares=None):
        self.ids, self.coords, self.sdf, self.shares = ids, coords, sdf, shares
        self.batch_size, self.seed, self.weights = batch_size, seed, weights
        self.set_epoch(0)

    def set_epoch(self, epoch: int) -> None:
        g = torch.Generator().manual_seed(self.seed * 100_003 + epoch)
        if self.weights is None:
            self.perm = torch.randperm(len(self.ids), generator=g)
        else:
            self.perm = torch.multinomial(self.weights, len(self.ids), replacement=True,
                                          generator=g)

    def __len__(self) -> int:
        return max(1, len(self.ids) // self.batch_size)

    def __getitem__(self, i: int):
        idx = self.perm[i * self.batch_size:(i + 1) * self.batch_size]
        if self.shares is None:
            return self.ids[idx], self.coords[idx], self.sdf[idx]
        return self.ids[idx], self.coords[idx], self.sdf[idx], self.shares[idx]


class PreparedDataModule(L.LightningDataModule):
    def __init__(self, shapes: list[PreparedShape], mode: str = "ngc", batch_size: int = 8192,
                 seed: int = 0, code_balance: float = 0.0, junction_weight: float = 0.0,
                 blend: float = 0.0):
        """blend: the blended union's width (0: the min; rows carry no shares)."""
        super().__init__()
        self.shapes, self.mode = shapes, mode
        ids, coords, sdf, self.n_codes = training_rows(shapes, mode)
        shared = shared_rows(shapes) if mode == "ngc" and junction_weight else None
        shares = blend_shares(shapes, blend) if mode == "ngc" and blend else None
        self.train_set = ShuffledBatches(ids, coords, sdf, batch_size, seed,
                                         row_weights(ids, code_balance, shared, junction_weight),
                                         shares)

    def set_epoch(self, epoch: int) -> None:
        self.train_set.set_epoch(epoch)

    def train_dataloader(self):
        return DataLoader(self.train_set, batch_size=None, shuffle=False, num_workers=0)
