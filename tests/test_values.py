"""The one rule for numbers (ngc_gen/values.py): configs, edit programs and GC annotations read
a number the same way; a quoted number is refused everywhere with the same words, and a value
keeps the type it was read with."""
import pytest
import yaml

from ngc_gen.app.runtime.checks import config_number
from ngc_gen.app.runtime.errors import ConfigError
from ngc_gen.data.annotations import annotation_from_dict
from ngc_gen.data.errors import DataError
from ngc_gen.edit.errors import EditError
from ngc_gen.edit.spec import check_program
from ngc_gen.values import NumberError, is_number, load_yaml, read_number

from .conftest import straight_gc
from .helpers import compose_config

QUOTED = "'30' is quoted text, not a number"


@pytest.mark.parametrize("value,kw,expected", [
    (30, {}, 30), (2.5, {}, 2.5), (3000.0, {"integer": True}, 3000), (0, {"minimum": 0}, 0)])
def test_numbers_keep_their_type(value, kw, expected):
    out = read_number(value, **kw)
    assert out == expected and type(out) is type(expected)


@pytest.mark.parametrize("value,kw,what", [
    ("30", {}, QUOTED), ("two", {"integer": True}, "not the text 'two'"),
    (True, {}, "not True"), (None, {}, "null"), (float("nan"), {}, "finite"),
    (2.5, {"integer": True}, "whole number"), (0, {"minimum": 1}, ">= 1"),
    (0, {"minimum": 0, "strict_minimum": True}, "> 0"), (2, {"maximum": 1}, "<= 1")])
def test_what_is_not_a_number(value, kw, what):
    with pytest.raises(NumberError, match="Fix:") as e:
        read_number(value, **kw)
    assert what in e.value.what
    assert not is_number(value) or kw


def test_yaml_reads_exponents_as_numbers_and_refuses_a_key_twice():
    d = load_yaml("a: 1e-3\nb: '30'\nc: 2\nd: 1.5E2\n")
    assert d == {"a": 0.001, "b": "30", "c": 2, "d": 150.0}
    assert isinstance(d["c"], int) and isinstance(d["b"], str)
    assert yaml.safe_load("a: 1e-3")["a"] == "1e-3"  # what PyYAML alone would do
    with pytest.raises(yaml.YAMLError, match="appears twice"):
        load_yaml("a: 1\na: 2\n")


def _program(degrees):
    return {"name": "p", "ops": [{"op": "twist", "gc": "tail", "t": 1.0, "degrees": degrees}]}


def test_a_quoted_number_is_refused_the_same_in_programs_annotations_and_configs():
    with pytest.raises(EditError, match=QUOTED + r".*Fix: write 30 without quotes"):
        check_program(_program("30"))
    with pytest.raises(EditError, match=r"degrees = 'thirty': must be a number"):
        check_program(_program("thirty"))
    gc = straight_gc("body", -0.3, 0.3)
    gc["keys"][0]["twist"] = "30"
    with pytest.raises(DataError, match=QUOTED + r".*Fix: write 30 without quotes"):
        annotation_from_dict({"name": "s", "mesh": "m.ply", "gcs": [gc]})
    cfg = compose_config("sample", ["n='30'", "out_dir=/tmp/unused"])
    with pytest.raises(ConfigError, match=QUOTED + r".*Fix: pass n=30 \(no quotes\)"):
        config_number(cfg, "n", integer=True, minimum=1)


def test_a_program_keeps_the_types_it_was_read_with():
    ops = check_program(load_yaml("name: p\nsmooth_union: 0\nops:\n"
                                  "  - {op: twist, gc: tail, t: 1.0, degrees: 30}\n"
                                  "  - {op: scale, gc: tail, t: null, factor: 1e-1}\n"))
    twist, scale = ops["ops"]
    assert type(twist["degrees"]) is int and type(twist["t"]) is float
    assert scale["factor"] == 0.1 and type(ops["smooth_union"]) is int
    written = yaml.safe_load(yaml.safe_dump(ops["ops"]))
    assert written == ops["ops"] and type(written[0]["degrees"]) is int
