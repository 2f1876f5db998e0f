"""The edit-op reference (ngc_gen/edit/spec.py) is the one source of op fields: it agrees with
the ops' signatures and the blends, its examples are valid programs, the table of
docs/edit_ops.md is generated from it, and checking a program against it needs no torch."""
import inspect
import re
import subprocess
import sys

import pytest
import yaml

from ngc_gen.edit import BLEND_PARAMS, EditError
from ngc_gen.edit.ops import OPS as GC_OPS
from ngc_gen.edit.program import CARRY_OPS, EditProgram, op_fields
from ngc_gen.edit.spec import BLEND_NAMES, OPS, TYPES, check_op, reference, reference_markdown

from ..helpers import ROOT

TABLE_START, TABLE_END = "<!-- edit-ops:start -->", "<!-- edit-ops:end -->"
OPS_PAGE = "docs/edit_ops.md"


@pytest.mark.parametrize("op", sorted(GC_OPS))
def test_gc_op_fields_are_the_function_signature(op):
    params = list(inspect.signature(GC_OPS[op]).parameters.values())[1:]
    from_signature = {"gc": True, **{p.name: p.default is inspect.Parameter.empty
                                     for p in params}}
    if op in CARRY_OPS:
        from_signature["carry"] = False
    assert op_fields(op) == from_signature


def test_every_op_is_described_and_blends_agree():
    assert set(OPS) == set(GC_OPS) | {"handles", "mix"}
    assert BLEND_NAMES == tuple(BLEND_PARAMS)
    for op, spec in OPS.items():
        assert spec.summary and all(f.type in TYPES for f in spec.fields.values()), op


@pytest.mark.parametrize("op", sorted(OPS))
def test_each_example_is_a_valid_op(op):
    entry = yaml.safe_load(OPS[op].example)
    assert entry["op"] == op
    assert check_op(entry, 0, "example") == entry
    EditProgram.from_dict({"name": "example", "ops": [entry]})


@pytest.mark.parametrize("entry, field", [
    ({"op": "twist", "gc": "tail", "t": "end", "degrees": 10}, "t"),
    ({"op": "bend", "gc": "tail", "indices": [1.5], "offsets": [0, 0, 1]}, "indices"),
    ({"op": "translate", "gc": "tail", "offset": [0, 1]}, "offset"),
    ({"op": "rotate", "gc": ["a", 3], "axis": [0, 0, 1], "degrees": 5}, "gc"),
    ({"op": "handles", "gc": "leg", "rotate": {"axis": [0, 0, 1]}}, "rotate"),
    ({"op": "mix", "gc": "head", "source": {"shape": "x", "when": 1}}, "source"),
])
def test_a_value_of_the_wrong_form_names_its_field_and_the_op_reference(entry, field):
    with pytest.raises(EditError) as e:
        check_op(entry, 2, "p.yaml")
    assert e.value.field == field and e.value.index == 2 and e.value.op == entry["op"]
    assert f"e.g. - {{op: {entry['op']}" in str(e.value) or "Fix:" in str(e.value)
    assert e.value.help == reference([entry["op"]])


def test_unknown_op_brings_the_whole_reference():
    with pytest.raises(EditError) as e:
        check_op({"op": "curl"}, 0, None)
    assert e.value.help == reference() and all(f"  {op}: " in e.value.help for op in OPS)


def test_docs_table_is_generated_from_the_spec():
    text = (ROOT / OPS_PAGE).read_text()
    block = re.search(re.escape(TABLE_START) + r"\n(.*?)\n" + re.escape(TABLE_END), text, re.S)
    assert block, f"{OPS_PAGE} has no {TABLE_START} ... {TABLE_END} block"
    assert block.group(1) == reference_markdown(), \
        f"{OPS_PAGE}'s edit-op table is stale: paste the output of `python -m ngc_gen.edit.spec`"


def test_the_docs_example_program_is_valid():
    text = (ROOT / OPS_PAGE).read_text()
    program = yaml.safe_load(re.search(r"```yaml\n(.*?)```", text, re.S).group(1))
    assert EditProgram.from_dict(program).name == program["name"]


def test_checking_a_program_needs_no_torch():
    code = ("import sys; import ngc_gen.app.stages.edit_shapes, ngc_gen.app.runtime.cli, ngc_gen.edit.spec; "
            "heavy = {'torch', 'lightning', 'numpy'} & set(sys.modules); "
            "assert not heavy, heavy")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
