"""Stable, telling names for automatic GCs: a trunk, and limbs by direction and position.

Directions are read in the mesh's body frame (``orient.Orientation``: given or detected up and
front, left = up x front; without one, +x front, +y left, +z up, the procedural creatures'
frame). The trunk is the branch of largest volume (length x squared thickness) of the largest
piece; a limb is named by where it points from its root (the end nearer the trunk): ``leg`` if
down, else ``limb_<front|back|left|right|up>``. Limbs that share a name get the side of their
root from the trunk's centre along the other two axes (``leg_front_left``), then a number.
Another piece's own trunk is ``piece_<position>``. The same mesh always gives the same names.
"""
from __future__ import annotations

import numpy as np

WORDS = (("back", "front"), ("right", "left"), ("down", "up"))  # (-, +) per axis x, y, z


def _direction(d: np.ndarray) -> tuple[int, int]:
    """(axis, sign index) of the dominant component of d."""
    a = int(np.argmax(np.abs(d)))
    return a, int(d[a] > 0)


def gc_names(curves: list[np.ndarray], volumes: list[float], components: list[int],
             frame: np.ndarray | None = None) -> list[str]:
    """Names for GCs given their curves (each (P, 3) sampled start to end), volumes and the
    skeleton piece each belongs to; ``frame`` (3, 3): rows front, left, up in world coordinates
    (``Orientation.matrix``; None: the world axes). Returns unique names in the input order."""
    if frame is not None:
        curves = [np.asarray(c, dtype=np.float64) @ np.asarray(frame, dtype=np.float64).T
                  for c in curves]
    n = len(curves)
    if n == 0:
        return []
    comps = np.asarray(components)
    vol = np.asarray(volumes, dtype=np.float64)
    comp_vol = {c: vol[comps == c].sum() for c in np.unique(comps)}
    main_comp = max(comp_vol, key=lambda c: (comp_vol[c], -c))
    trunks = {c: int(np.flatnonzero(comps == c)[np.argmax(vol[comps == c])]) for c in comp_vol}
    main = curves[trunks[main_comp]]
    center = main.mean(axis=0)
    size = float(np.ptp(np.concatenate(curves), axis=0).max()) or 1.0
    base, roots = [], np.zeros((n, 3))
    for i, c in enumerate(curves):
        if i == trunks[main_comp]:
            base.append("trunk")
            roots[i] = center
            continue
        if i == trunks[comps[i]]:
            off = c.mean(axis=0) - center
            a, s = _direction(off)
            base.append(f"piece_{WORDS[a][s]}")
            roots[i] = c.mean(axis=0)
            continue
        trunk = curves[trunks[comps[i]]]
        d_start = np.linalg.norm(trunk - c[0], axis=1).min()
        d_end = np.linalg.norm(trunk - c[-1], axis=1).min()
        root, tip = (c[0], c[-1]) if d_start <= d_end else (c[-1], c[0])
        a, s = _direction(tip - root)
        base.append("leg" if (a, s) == (2, 0) else f"limb_{WORDS[a][s]}")
        roots[i] = c.mean(axis=0)
    names = list(base)
    for b in sorted(set(base)):
        group = [i for i in range(n) if base[i] == b]
        if len(group) < 2:
            continue
        word = b.split("_")[1] if "_" in b else "down"
        named_axis = next(a for a in range(3) if word in WORDS[a])
        for a in range(3):  # side of the root from the trunk's centre, where it is clear
            off = roots[group, a] - center[a]
            if a == named_axis or np.ptp(off) < 0.05 * size:
                continue
            for i, o in zip(group, off):
                if abs(o) >= 0.02 * size:
                    names[i] += f"_{WORDS[a][int(o > 0)]}"
    # still equal: number them by root position (x, then y, then z)
    for nm in sorted(set(names)):
        group = [i for i in range(n) if names[i] == nm]
        if len(group) > 1:
            order = sorted(group, key=lambda i: tuple(np.round(roots[i], 6)))
            for k, i in enumerate(order):
                names[i] = f"{nm}_{k + 1}"
    return names
