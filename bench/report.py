"""bench/README.md's tables and README.md's "Results at a glance", assembled from
bench/results/<name>.json: one source for every figure.

    python -m bench.report            # rewrite the tables (make bench-report)
    python -m bench.report --check    # exit 1 and show the difference if a table is stale

Each bench registered in `bench.BENCHES` owns its formatters: `table(result)` (its block in
bench/README.md; without one, its top-level scalars as key / value rows) and, optionally,
`headline(result)` (its row in the README's glance table).
A page's block between `<!-- table:<name> -->` and `<!-- /table:<name> -->` is replaced by the
bench's table and one line from its machine record (bench/_harness.py); the `glance` block by
one headline per bench. A registered bench with no section in bench/README.md gets one appended
(a heading and its block), for its prose to be written around. Nothing else on the pages is
touched; tests/bench/test_bench_report.py fails when a page differs from what this writes.
Standard library only (a bench module imports the heavy libraries inside its functions).
"""
from __future__ import annotations

import argparse
import difflib
import importlib
import json
import re
import sys
from pathlib import Path

from bench import BENCHES
from bench._tables import rows_table

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench/results"
README = ROOT / "bench/README.md"
PAGES = (README, ROOT / "README.md")   # the project README holds the `glance` block
BLOCK = re.compile(r"(<!-- table:(?P<name>[a-z_]+) -->\n)(?P<body>.*?)(<!-- /table:(?P=name) -->)",
                   re.S)
#: the README's glance rows, reader's order: the end-to-end demo and the paper's results first;
#: a registered bench not named here follows in `BENCHES` order
GLANCE_ORDER = ("demo", "fit", "fit_ablation", "deform", "extract", "sparse_settings",
                "reconstruct", "generate", "condition", "animals", "transfer", "autogc", "editor",
                "cli", "geometry", "ddp", "up_axis")


def machine_line(name: str, res: dict) -> str:
    """One line from the result's machine record. A record without `dirty` (None) comes from a
    result written before the harness: its commit is the one that recorded the result."""
    m = res.get("machine") or {}
    commit = (m.get("commit") or "unknown")[:7]
    if m.get("dirty") is None:
        where = f"Recorded in commit {commit}"
    else:
        where = f"Measured at commit {commit}" + (" with uncommitted changes" if m["dirty"]
                                                  else "")
    date = (m.get("date_utc") or "unknown date").replace("T", " ").replace("Z", " UTC")
    parts = []
    if m.get("cpus") is not None:
        parts.append(f"{m['cpus']} CPUs")
    threads = m.get("torch_threads")
    if threads is not None:
        parts.append(f"{threads} torch thread{'s' if threads != 1 else ''}")
    load = [f"{m[k]:.2f} {w}" for k, w in (("load_1min_before", "before"),
                                           ("load_1min_after", "after"))
            if m.get(k) is not None]
    if load:
        parts.append("1-minute load " + ", ".join(load))
    return (f"_{where}, {date}" + (f"; {', '.join(parts)}" if parts else "")
            + f" (`bench/results/{name}.json`)._")


def module(name: str, package: str = "bench"):
    """The bench's module (`<package>.<name>`), which holds its `table` and `headline`."""
    return importlib.import_module(f"{package}.{name}")


def scalars(res: dict) -> str:
    """The table of a bench that has no `table` of its own: its top-level numbers, strings and
    booleans as key / value rows."""
    rows = [[f"`{k}`", f"{v:.4g}" if isinstance(v, float) else v] for k, v in res.items()
            if isinstance(v, (int, float, str, bool)) and k != "machine"]
    return "\n".join(rows_table(["key", "value"], rows))


def glance(results: Path = RESULTS, benches=BENCHES, package: str = "bench") -> str:
    """The README's results table: one headline per bench that has one and a result."""
    order = [b for b in GLANCE_ORDER if b in benches] + \
        [b for b in benches if b not in GLANCE_ORDER]
    rows = []
    for name in order:
        path = Path(results) / f"{name}.json"
        headline = getattr(module(name, package), "headline", None)
        if headline is not None and path.is_file():
            rows.append([f"[{name}](bench/README.md#{name})",
                         headline(json.loads(path.read_text()))])
    return "\n".join(rows_table(["benchmark", "headline (latest result)"], rows)) + "\n"


def block(name: str, results: Path = RESULTS, benches=BENCHES, package: str = "bench") -> str:
    """What a page holds between the markers of `name` (`glance`: the project README's
    results table)."""
    if name == "glance":
        return glance(results, benches, package)
    path = Path(results) / f"{name}.json"
    if not path.is_file():
        return f"No result yet: run `make bench-{name.replace('_', '-')}`.\n"
    res = json.loads(path.read_text())
    table = getattr(module(name, package), "table", scalars)
    return f"{table(res)}\n\n{machine_line(name, res)}\n"


def sections_added(text: str, benches=BENCHES) -> str:
    """bench/README.md with a section (heading and empty block) appended for each registered
    bench that has no block yet."""
    have = set(blocks_in(text))
    for name in benches:
        if name not in have:
            text = (text.rstrip("\n") + f"\n\n## {name}\n\n"
                    f"<!-- table:{name} -->\n<!-- /table:{name} -->\n")
    return text


def render(text: str, results: Path = RESULTS, benches=BENCHES, package: str = "bench") -> str:
    """`text` (a page) with every table block regenerated."""
    def one(m):
        return m.group(1) + block(m.group("name"), results, benches, package) + m.group(4)
    return BLOCK.sub(one, text)


def blocks_in(text: str) -> list[str]:
    return [m.group("name") for m in BLOCK.finditer(text)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if a page is stale")
    args = ap.parse_args(argv)
    stale = 0
    for page in PAGES:
        old = page.read_text()
        new = render(sections_added(old) if page == README else old)
        if new == old:
            continue
        name = str(page.relative_to(ROOT))
        if args.check:
            sys.stdout.writelines(difflib.unified_diff(
                old.splitlines(True), new.splitlines(True), name, "generated"))
            stale = 1
            continue
        from ngc_gen.data.atomic import atomic_write_text

        atomic_write_text(page, new)
        print(f"rewrote {name}: {', '.join(blocks_in(new))}")
    return stale


if __name__ == "__main__":
    sys.exit(main())
