"""bench/README.md's tables are generated from bench/results/*.json (bench/report.py), every
result carries the harness's machine record, and every bench is registered, has its section and
its make target."""
from __future__ import annotations

import ast
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import bench
from bench import _harness, report

ROOT = Path(report.ROOT)
BENCHES = sorted(bench.BENCHES)
MODULES = sorted(p.stem for p in (ROOT / "bench").glob("*.py") if not p.stem.startswith("_")
                 and p.stem != "report")
RESULTS = sorted(p.stem for p in (ROOT / "bench/results").glob("*.json"))


def test_every_bench_module_is_registered():
    assert MODULES == BENCHES, ("bench/<name>.py and bench/__init__.py's BENCHES differ "
                                "(a helper module's name starts with _)")


def test_the_readme_tables_equal_the_results():
    text = report.README.read_text()
    fresh = report.render(text)
    assert fresh == text, ("bench/README.md differs from bench/results/*.json: run "
                           "`make bench-report` (python -m bench.report)")


def test_the_project_readme_results_equal_the_results(tmp_path):
    """README.md's "Results at a glance" is generated too, and follows a changed result."""
    text = (ROOT / "README.md").read_text()
    assert "<!-- table:glance -->" in text
    assert report.render(text) == text, ("README.md's results table differs from "
                                         "bench/results/*.json: run `make bench-report`")
    shutil.copytree(ROOT / "bench/results", tmp_path / "results")
    path = tmp_path / "results/ddp.json"
    res = json.loads(path.read_text())
    res["speedup_samples_per_s"] = 1.91
    path.write_text(json.dumps(res))
    assert "1.91x the samples per second" in report.render(text, tmp_path / "results")


def test_a_changed_result_changes_its_table(tmp_path):
    """The check above has teeth: a figure changed in a JSON shows in the regenerated text."""
    shutil.copytree(ROOT / "bench/results", tmp_path / "results")
    text = report.README.read_text()
    path = tmp_path / "results/deform.json"
    res = json.loads(path.read_text())
    res["cases"][0]["ngc"]["eps_v"] *= 3.0
    path.write_text(json.dumps(res))
    assert report.render(text, tmp_path / "results") != text
    (tmp_path / "results/ddp.json").unlink()      # a missing result says how to make it
    assert "run `make bench-ddp`" in report.block("ddp", tmp_path / "results")


def test_the_fit_table_lists_the_junctions_when_measured(tmp_path):
    """bench/fit.py's `junctions` entries get a table and a targets line."""
    shutil.copytree(ROOT / "bench/results", tmp_path / "results")
    path = tmp_path / "results/fit.json"
    res = json.loads(path.read_text())
    row = {"name": "ant", "gcs": "annotated", "recipe": "before", "method": "ngc",
           "junction_ratio_dist": 1.87, "junction_ratio_normal": 1.25, "extra_pieces": 2,
           "nc": 0.961, "fscore": 0.982}
    res["junctions"] = [row, {**row, "recipe": "deepsdf", "method": "deepsdf",
                              "junction_ratio_dist": 1.1, "extra_pieces": 0}]
    path.write_text(json.dumps(res))
    block = report.block("fit", tmp_path / "results")
    assert "| ant | annotated | before | 1.87 | 1.25 | 2 | 0.961 | 0.982 | - |" in block
    res["ceiling"]["per_shape"]["ant"].update(junction_ratio_dist=1.4, junction_ratio_normal=1.6)
    path.write_text(json.dumps(res))
    block = report.block("fit", tmp_path / "results")
    assert "| ant | annotated | before | 1.87 | 1.25 | 2 | 0.961 | 0.982 | 1.40 / 1.60 |" in block
    assert "before: junction / elsewhere <= 1.3 (distance and normal) on 0 of 1 meshes, worst " \
           "1.87; 2 extra pieces" in block
    assert "deepsdf: junction / elsewhere <= 1.3 (distance and normal) on 1 of 1" in block


def test_every_bench_has_a_section_and_every_result_a_table():
    text = report.README.read_text()
    headings = re.findall(r"^## (\S+)$", text, re.M)
    blocks = report.blocks_in(text)
    for name in BENCHES:
        assert name in headings, f"bench/README.md has no '## {name}' section"
        assert name in blocks, f"bench/README.md has no table block for {name}"
    for name in RESULTS:
        assert name in blocks, f"bench/results/{name}.json has no table in bench/README.md"
        assert name in BENCHES, f"bench/results/{name}.json: no bench/{name}.py writes it"


@pytest.mark.parametrize("name", RESULTS)
def test_every_result_carries_the_machine_record(name):
    res = json.loads((ROOT / f"bench/results/{name}.json").read_text())
    assert tuple(res.get("machine") or ()) == _harness.MACHINE_KEYS, name
    old = re.compile(r"load_avg|loadavg|cpu_count")
    stray = []

    def walk(x, where):
        if isinstance(x, dict):
            for k, v in x.items():
                if old.search(k):
                    stray.append(f"{where}.{k}")
                walk(v, f"{where}.{k}")
        elif isinstance(x, list):
            for i, v in enumerate(x):
                walk(v, f"{where}[{i}]")
    walk(res, name)
    assert not stray, f"machine figures outside the record: {stray}"


@pytest.mark.parametrize("name", BENCHES)
def test_every_bench_writes_through_the_harness(name):
    src = (ROOT / f"bench/{name}.py").read_text()
    assert "Bench(" in src and ".write(" in src, f"bench/{name}.py does not write via Bench"
    assert "getloadavg" not in src, f"bench/{name}.py reads the load itself"
    assert "platform.python_version" not in src, f"bench/{name}.py records the machine itself"


def test_every_bench_has_a_make_target_that_runs_its_module():
    listed = subprocess.run([sys.executable, "-m", "bench"], cwd=ROOT, check=True,
                            capture_output=True, text=True).stdout.split()
    assert listed == [b.replace("_", "-") for b in bench.BENCHES]    # what `make bench` loops
    for name in BENCHES:
        target = f"bench-{name.replace('_', '-')}"
        out = subprocess.run(["make", "-n", "--no-print-directory", target], cwd=ROOT,
                             capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        assert re.search(rf"-m bench\.{name}\b", out.stdout.splitlines()[-1]), \
            f"make {target} does not run python -m bench.{name}"


def test_the_bench_modules_keep_to_the_house_rules():
    """Run as `python -m bench.<name>`: no sys.path edits; a bench reads another bench's fit
    through the harness's cache and shares code through bench/_*.py helpers, never by
    importing the other bench's module; no function over 80 lines."""
    long, imports = [], []
    for path in sorted((ROOT / "bench").glob("*.py")):
        src = path.read_text()
        assert "sys.path.insert" not in src, path.name
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and node.end_lineno - node.lineno + 1 > 80:
                long.append(f"{path.name}:{node.name}")
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            for n in names:
                parts = n.split(".")
                if (parts[0] == "bench" and len(parts) > 1 and parts[1] in bench.BENCHES) \
                        or parts[0] in bench.BENCHES:
                    imports.append(f"{path.name}: {n}")
    assert not long, f"functions over 80 lines: {long}"
    assert not imports, f"a bench imported by another module: {imports}"


def test_the_report_runs_on_the_standard_library():
    """make bench-report runs under a bare python3: importing the report and every bench
    module loads no numpy, torch or omegaconf (a bench imports them inside its functions)."""
    code = ("import sys, importlib, bench, bench.report; "
            "[importlib.import_module(f'bench.{b}') for b in bench.BENCHES]; "
            "bad = {'numpy', 'torch', 'omegaconf', 'lightning', 'trimesh'} & set(sys.modules); "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True)


def test_a_partial_seams_run_keeps_the_other_meshes_entries():
    from bench._seams import crop, merge_rows

    def r(name, gcs, recipe, nc):
        return {"name": name, "gcs": gcs, "recipe": recipe, "nc": nc}

    old = [r("ant", "auto", "before", 0.9), r("cow", "rig", "before", 0.97),
           r("ant", "auto", "after", 0.91)]
    new = [r("ant", "auto", "after", 0.95)]
    got = merge_rows(old, new)
    assert [(x["name"], x["recipe"], x["nc"]) for x in got] == [
        ("ant", "before", 0.9), ("ant", "after", 0.95), ("cow", "before", 0.97)]
    import numpy as np
    import trimesh
    box = trimesh.creation.box(extents=(2, 2, 2))
    part = crop(box, np.array([1.0, 1.0, 1.0]), 0.5)          # the corner's faces only
    assert len(part.faces) > 0
    assert np.linalg.norm(part.vertices - 1.0, axis=1).max() < 0.6    # the big faces split


def test_the_transfer_section_shows_the_generators_spread_and_the_heldout_reconstruction():
    """A reader judges the rig-vs-transferred generator gap against the spread over sample
    sets, and sees the held-out species' F-scores; an older result without them still renders."""
    base = json.loads((ROOT / "bench/results/transfer.json").read_text())
    r = {**base,
         "generator": {"rig": {"mmd_cd": 0.0103, "nna_cd": 0.648,
                               "sd_over_sets": {"mmd_cd": 0.0006, "nna_cd": 0.065}},
                       "transferred": {"mmd_cd": 0.0116, "nna_cd": 0.658}},
         "reconstruct_heldout": {"fscore": {"husky_rest": 0.916, "deer_rest": 0.885}}}
    from bench import transfer

    text = transfer.table(r)
    assert "rig MMD-CD 10.300 x1e-3, 1-NNA 64.8% (sd over sets: MMD-CD 0.600, 1-NNA 6.5%)" in text
    assert "transferred MMD-CD 11.600 x1e-3, 1-NNA 65.8%." in text   # no spread recorded
    assert "F-score@0.01 deer_rest 0.885, husky_rest 0.916." in text
    old = transfer.table({**base, "generator": None, "reconstruct_heldout": None})
    assert "not measured yet" in old and "Held-out species" not in old
    # at a glance: the generator gap, relative, as the line reads it
    assert "MMD-CD +12.6%, 1-NNA +1.5%" in transfer.headline(r)
    assert "generator" not in transfer.headline({**base, "generator": None})


def test_the_cli_table_shows_the_malformed_mesh_files_when_measured():
    from bench import cli

    base = json.loads((ROOT / "bench/results/cli.json").read_text())
    base = {k: v for k, v in base.items() if not k.startswith("malformed_mesh")}
    assert "Malformed" not in cli.table(base)                 # an older result still renders
    r = {**base, "malformed_mesh_s": {"gltf_bad_json": 1.1, "off_no_faces": 2.4},
         "malformed_mesh_slowest_s": 2.4,
         "targets": {**base["targets"], "malformed_mesh_slowest_s": 2.0}}
    assert ("exit 2 after 1.10-2.40 s, slowest 2.40 s; 1 of 2 within the 2 s target"
            in cli.table(r))
