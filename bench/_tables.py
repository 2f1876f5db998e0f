"""Small formats the benches' tables share (standard library only): counts, percentages,
spans, powers of ten and Markdown tables."""
from __future__ import annotations


def count(n: float) -> str:
    """2.1M, 40k, 512."""
    if n >= 1e6:
        return f"{n / 1e6:.1f}M"
    if n >= 1e3:
        return f"{n / 1e3:.0f}k"
    return f"{n:.0f}"


def pct(x: float, digits: int = 2) -> str:
    return f"{100 * x:.{digits}f}%"


def rows_table(header: list[str], rows: list[list]) -> list[str]:
    """A Markdown table's lines."""
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return out


def span(values, fmt: str = ".2f") -> str:
    """min-max of values."""
    return f"{min(values):{fmt}}-{max(values):{fmt}}"


def sci(x: float, exp: int = -3) -> str:
    """x in units of 10^exp: sci(6.6e-3) -> '6.60e-3'."""
    return f"{x / 10.0 ** exp:.2f}e{exp}"
