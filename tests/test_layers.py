"""The package's layering (docs/architecture.md): imports point down the layer list (import-linter's
contract in pyproject.toml), and only the runner layer changes process-wide state."""
import os
import re
import subprocess
import sys
from pathlib import Path

from .helpers import ROOT

# calls that change the whole process: torch threads, log handlers, warning filters, resolvers
# numba.set_num_threads is thread-local (it sizes the calling thread's parallel regions, following
# the torch thread count the app layer set), so it is not process-wide state
PROCESS_WIDE = re.compile(r"(?<!numba\.)set_num_threads\(|warnings\.(filterwarnings|simplefilter)\(|"
                          r"register_new_resolver\(|logging\.basicConfig\(|\.(add|remove)Handler\(")
# a line marked with this comment puts back a value something else reset (numba's OpenMP start
# resets torch's thread count): it keeps the caller's state, it does not set its own
RESTORES = "# puts back the caller's count"
# a line so marked runs in a worker process the package spawned itself (its own state, not the
# user's process)
WORKER = "# in a worker process we spawned"


def test_imports_follow_the_layers():
    lint = Path(sys.executable).parent / "lint-imports"
    r = subprocess.run([str(lint), "--no-cache"], cwd=ROOT, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "1 kept, 0 broken" in r.stdout


def test_only_the_runner_layer_sets_process_wide_state():
    offenders = [f"{p.relative_to(ROOT)}:{i}" for p in sorted((ROOT / "ngc_gen").rglob("*.py"))
                 if "app" not in p.relative_to(ROOT / "ngc_gen").parts[:1]
                 for i, line in enumerate(p.read_text().splitlines(), 1)
                 if PROCESS_WIDE.search(line)
                 and not line.rstrip().endswith((RESTORES, WORKER))]
    assert not offenders, offenders


def import_cycles(graph) -> list[list[str]]:
    """The circles of a grimp import graph: its strongly connected components of more than one
    module (a module importing itself does not count). Every import statement counts, the
    function-local ones included, so a circle broken only at run time is still found."""
    import numpy as np
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    modules = sorted(graph.modules)
    index = {m: i for i, m in enumerate(modules)}
    edges = [(index[m], index[d]) for m in modules
             for d in graph.find_modules_directly_imported_by(m) if d != m]
    rows, cols = zip(*edges) if edges else ((), ())
    adjacency = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(modules),) * 2)
    _, label = connected_components(adjacency, directed=True, connection="strong")
    sizes = np.bincount(label)
    return [sorted(modules[i] for i in np.flatnonzero(label == k))
            for k in np.flatnonzero(sizes > 1)]


def test_no_import_circle_between_modules():
    import grimp

    graph = grimp.build_graph("ngc_gen", include_external_packages=False)
    assert import_cycles(graph) == [], "import circles (break them by moving the shared code " \
                                       "into a module both can import)"


def test_a_circle_is_found_when_one_is_added():
    import grimp

    graph = grimp.build_graph("ngc_gen", include_external_packages=False)
    graph.add_import(importer="ngc_gen.geometry.curves", imported="ngc_gen.app.stages.pipeline")
    found = import_cycles(graph)
    assert len(found) == 1 and {"ngc_gen.geometry.curves", "ngc_gen.app.stages.pipeline"} <= set(found[0])


def test_no_module_name_is_repeated_across_layers():
    """A module's name says which room it is in: `app/stages/fit.py` and no second `fit.py`
    elsewhere (`errors.py`, each layer's own error type, is the one name every layer may hold)."""
    from collections import defaultdict

    homes = defaultdict(list)
    for p in (ROOT / "ngc_gen").rglob("*.py"):
        if p.name not in ("__init__.py", "errors.py"):
            homes[p.stem].append(p.relative_to(ROOT / "ngc_gen").as_posix())
    assert {k: v for k, v in homes.items() if len(v) > 1} == {}
