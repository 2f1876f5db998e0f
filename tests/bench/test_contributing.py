"""docs/contributing.md's "Add a bench" recipe works as written: its example module, registered
as a bench, runs, writes its result through the harness, and `make bench-report`'s renderer gives
it a section in bench/README.md with its table and a row in the README's glance table."""
from __future__ import annotations

import json
import re
import sys

from bench import _harness, report

DOC = report.ROOT / "docs/contributing.md"


def example() -> str:
    """The first python block of the doc's "Add a bench" section."""
    section = DOC.read_text().split("## Add a bench", 1)[1].split("\n## ", 1)[0]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_add_a_bench_example_runs_and_renders(tmp_path, monkeypatch):
    pkg = tmp_path / "toybench"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('BENCHES = ("toy",)\n')
    (pkg / "toy.py").write_text(example())
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("toybench", "toybench.toy"):      # the modules leave with the test
        monkeypatch.setitem(sys.modules, name, None)
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setattr(_harness, "RESULTS", tmp_path / "results")
    monkeypatch.setattr(sys, "argv", ["toy", "--n", "1000"])
    from toybench import toy

    toy.main()
    result = json.loads((tmp_path / "results/toy.json").read_text())
    assert result["n"] == 1000 and tuple(result["machine"]) == _harness.MACHINE_KEYS

    page = report.sections_added("# Benchmarks\n\nIntro.\n", benches=("toy",))
    assert "## toy\n\n<!-- table:toy -->\n<!-- /table:toy -->" in page
    assert report.sections_added(page, benches=("toy",)) == page      # added once
    page = report.render(page, tmp_path / "results", ("toy",), "toybench")
    assert "| numbers summed | seconds |\n|---|---|\n| 1000 |" in page
    assert "(`bench/results/toy.json`)._" in page                    # its machine line
    readme = "<!-- table:glance -->\n<!-- /table:glance -->\n"
    glance = report.render(readme, tmp_path / "results", ("toy",), "toybench")
    assert "| [toy](bench/README.md#toy) | 1000 numbers summed in " in glance
    del toy.table, toy.headline               # a bench that has not written them yet
    page = report.render(page, tmp_path / "results", ("toy",), "toybench")
    assert "| key | value |\n|---|---|\n| `n` | 1000 |" in page
    assert "[toy]" not in report.render(readme, tmp_path / "results", ("toy",), "toybench")


def test_a_registered_bench_without_a_section_gets_one():
    """Every shipped bench has its section; a newly registered one gets a section appended by
    `make bench-report` (and `python -m bench.report --check` reports bench/README.md stale)."""
    text = report.README.read_text()
    assert report.sections_added(text) == text                       # every bench has one
    assert "## newbench" in report.sections_added(text, benches=(*report.BENCHES, "newbench"))
