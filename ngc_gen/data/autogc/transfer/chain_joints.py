"""Where two template GCs that share one skeleton path (a neck and its head) meet: at a waist
of the path's thickness, else at its sharpest bend, near where the template's lengths put the
joint (docs/transfer.md, "How a template is placed", step 2)."""
from __future__ import annotations

import numpy as np

WAIST_RISE = 1.1  # a waist: the path this much thicker on both sides of it, within the window


def joint_near(P: np.ndarray, radius: np.ndarray, arc: np.ndarray, i: int, end: int,
               window: float = 0.2) -> int:
    """The index within `window` x the length of the path (P, 3; thickness `radius`, arc
    lengths `arc`) of index i where two parts meet: its waist (``waist_near``) up to index
    `end` where it has one, else where it bends most (``bend_near``). `end`: where the
    template's chain ends on the path; what runs on past it (an elephant's trunk, thinning
    with rings and the tusks' junction along it) is the last part's whole, its waists no
    joint."""
    w = waist_near(radius[: end + 1], arc[: end + 1], i, window, arc[-1]) if i <= end else None
    return bend_near(P, arc, i, window) if w is None else w


def _candidates(arc: np.ndarray, i: int, window: float, length: float | None = None) -> np.ndarray:
    """Indices within `window` x the path's `length` (default: arc's) of i, half a window
    clear of either end."""
    whole = arc[-1] if length is None else length
    w = window * whole
    return np.flatnonzero((np.abs(arc - arc[i]) <= w) & (arc >= w / 2) & (arc <= whole - w / 2))


def waist_near(radius: np.ndarray, arc: np.ndarray, i: int, window: float = 0.2,
               length: float | None = None) -> int | None:
    """The thinnest index within `window` x the path's `length` (default: arc's) of i, on the
    path (arc lengths `arc`) or the part of it given, with the path WAIST_RISE x
    thicker both before and after it within that window, or None. A neck thins to its top and
    the skull is wider than that (the poll, behind the jaw): the head begins at that waist,
    which a head held level with a bent muzzle does not show as its sharpest bend (the
    forehead-to-muzzle bend is sharper); a neck that thins into a narrower head has none."""
    w = window * (arc[-1] if length is None else length)
    cand = _candidates(arc, i, window, length)
    cand = cand[(cand > 0) & (cand < len(arc) - 1)]
    if len(cand) == 0:
        return None
    near = np.abs(arc[None, :] - arc[cand, None]) <= w                   # (C, P)
    after = np.where(near & (arc[None, :] > arc[cand, None]), radius[None, :], 0.0).max(1)
    before = np.where(near & (arc[None, :] < arc[cand, None]), radius[None, :], 0.0).max(1)
    ok = cand[(after >= WAIST_RISE * radius[cand]) & (before >= WAIST_RISE * radius[cand])]
    if len(ok) == 0:
        return None
    return int(ok[int(np.argmin(radius[ok]))])


def bend_near(P: np.ndarray, arc: np.ndarray, i: int, window: float = 0.2) -> int:
    """The index within `window` x the path's length of i where the path (P, 3) bends most
    (the angle between the chords over that window before and after): a neck meets its head
    at a bend, not at a fixed share of the length."""
    w = window * arc[-1]
    cand = _candidates(arc, i, window)
    if len(cand) == 0:
        return i
    before = P[cand] - P[np.searchsorted(arc, arc[cand] - w / 2).clip(0, len(P) - 1)]
    after = P[np.searchsorted(arc, arc[cand] + w / 2).clip(0, len(P) - 1)] - P[cand]
    cos = (before * after).sum(1) / np.maximum(
        np.linalg.norm(before, axis=1) * np.linalg.norm(after, axis=1), 1e-12)
    return int(np.clip(cand[int(np.argmin(cos))], 1, len(P) - 2))
