"""How much memory an extraction at a resolution needs, how much the machine has, and the largest
resolution that fits: checked before any grid is allocated, so `extract.resolution=100000` is
refused in a moment instead of growing until the machine kills the process.

Standard library only (no torch, numpy or trimesh): the entry points check a resolution before
the heavy modules load.

The model (bytes for an R^3 grid, measured by peak RSS on the fitted ant, sparse path):
R = 128, 256, 384, 512 took 16, 78, 200, 380 MB, i.e. ~940 R^2 + ~1 R^3 bytes (the surface's
blocks, points and faces grow with R^2; the speck mask with R^3). `SAFETY` doubles it for
shapes with more surface than the ant. The reference paths ("prefiltered", "dense") hold the
whole grid: float32 values, the covered mask and marching cubes' masks and counts, ~12 bytes
per point on top; `keep_values` adds the float32 (R, R, R) grid.
"""
from __future__ import annotations

import os

SURFACE_BYTES = 940.0   # per R^2 (sparse path)
VOLUME_BYTES = 1.0      # per R^3 (sparse path)
GRID_BYTES = 12.0       # per R^3 more for the reference paths
VALUES_BYTES = 4.0      # per R^3 more with keep_values
SAFETY = 2.0
USABLE = 0.8            # of the available memory: the rest for the model, the OS and others


class GridTooLarge(MemoryError):
    """A resolution whose grid would not fit in memory; `largest` is the largest that does.
    The entry points report it as a one-line error (exit 2)."""

    def __init__(self, what: str, reason: str, resolution: int, largest: int, needed: int,
                 available: int):
        super().__init__(f"{what} {resolution} {reason}")
        self.reason, self.resolution, self.largest = reason, resolution, largest
        self.needed, self.available = needed, available


def extraction_bytes(resolution: int, method: str = "sparse", keep_values: bool = False) -> int:
    """The memory an extraction at `resolution`^3 may need (bytes, the model above)."""
    r = float(resolution)
    per_volume = VOLUME_BYTES + (GRID_BYTES if method != "sparse" else 0.0) \
        + (VALUES_BYTES if keep_values else 0.0)
    return int(SAFETY * (SURFACE_BYTES * r * r + per_volume * r ** 3))


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            text = f.read().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def available_bytes() -> int:
    """Memory this process can still take: the kernel's MemAvailable, or less where a cgroup
    limit (v2 memory.max, v1 limit_in_bytes) leaves less. Falls back to the physical memory."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    for limit, usage in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                         ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                          "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        lim, use = _read_int(limit), _read_int(usage)
        if lim is not None and use is not None and lim < 1 << 60:  # "max" / no limit: skipped
            found.append(max(lim - use, 0))
    if not found:
        try:
            found.append(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
        except (ValueError, OSError, AttributeError):
            found.append(8 << 30)
    return min(found)


def largest_resolution(budget: int, method: str = "sparse", keep_values: bool = False) -> int:
    """The largest R whose extraction fits in `budget` bytes (0 if none does)."""
    lo, hi = 0, 1
    while extraction_bytes(hi, method, keep_values) <= budget:
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if extraction_bytes(mid, method, keep_values) <= budget else (lo, mid)
    return lo


def check_resolution(resolution: int, method: str = "sparse", keep_values: bool = False,
                     available: int | None = None, what: str = "resolution") -> None:
    """GridTooLarge if an extraction at `resolution` may need more than USABLE of the memory
    available now (`available`, default `available_bytes()`); `what` names the setting."""
    available = available_bytes() if available is None else int(available)
    budget = int(USABLE * available)
    needed = extraction_bytes(resolution, method, keep_values)
    if needed <= budget:
        return
    largest = largest_resolution(budget, method, keep_values)
    raise GridTooLarge(
        what, f"needs about {_gib(needed)} for its {resolution}^3 grid, more than the "
        f"{_gib(budget)} this machine can spare now ({_gib(available)} available); the largest "
        f"resolution that fits is {largest}", resolution, largest, needed, available)


def _gib(n: int) -> str:
    return f"{n / 2 ** 30:.3g} GiB" if n < 2 ** 50 else f"{n / 2 ** 40:.3g} TiB"
