"""Numbers as users write them, read one way everywhere: in Hydra configs and overrides
(`n=8`, `extract.resolution=128`), in edit programs (`degrees: 30`) and in GC annotations.

The rule: a number is an int or a float (not a bool, finite). A quoted number (`n='3'`,
`degrees: "30"`) is text and is refused with the same message everywhere ("write it without
quotes"), so a value is always written back with the type it was read as. YAML files are read
with `load_yaml`, whose floats follow YAML 1.2 and OmegaConf (`1e-3` is a number; PyYAML's
SafeLoader alone reads it as the text '1e-3') and which refuses a key given twice.

Standard library and PyYAML only: the entry points check numbers before torch loads. The
callers wrap `NumberError` in their own error type, which adds where the value was.
"""
from __future__ import annotations

import math
import re

import yaml


class NumberError(ValueError):
    """A value that is not the number asked for. `what`: what is wrong (with the value);
    `want`: the number asked for ("a whole number >= 1"); `quoted`: the text of a quoted
    number, else None; `example`: a value that would do; `fix`: what to write (YAML wording;
    `config_fix` gives the command-line wording)."""

    def __init__(self, what: str, want: str, example: str, quoted: str | None = None):
        self.what, self.want, self.example, self.quoted = what, want, example, quoted
        self.fix = (f"write {quoted} without quotes" if quoted is not None
                    else f"write {want}, e.g. {example}")
        super().__init__(f"{what}. Fix: {self.fix}")

    def config_fix(self, key: str) -> str:
        """The fix as a command-line override of `key`."""
        if self.quoted is not None:
            return f"pass {key}={self.quoted} (no quotes)"
        return f"pass {key}=<{self.want}>, e.g. {key}={self.example}"


_NUMBER_TEXT = re.compile(r"^\s*[-+]?(\d[\d_]*\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$|"
                          r"^\s*[-+]?(inf|nan|\.inf|\.nan)\s*$", re.IGNORECASE)


def looks_like_number(text: str) -> bool:
    """True for text a user meant as a number (`'30'`, `'1e-3'`, `' 2.5 '`)."""
    return bool(_NUMBER_TEXT.match(text))


def read_number(value, *, integer: bool = False, minimum=None, maximum=None,
                strict_minimum: bool = False):
    """`value` as a number: an int or float, finite; `integer`: a whole number (an integral
    float such as 3000.0 is read as the int 3000); within [minimum, maximum] (`strict_minimum`:
    > minimum). Returns it with the type it was given (int stays int, float stays float).
    NumberError otherwise, saying what to write instead."""
    want = "a whole number" if integer else "a number"
    if minimum is not None:
        want += f" {'>' if strict_minimum else '>='} {minimum:g}"
    if maximum is not None:
        want += f"{' and' if minimum is not None else ''} <= {maximum:g}"
    example = _example(integer, minimum, maximum, strict_minimum)
    if isinstance(value, str):
        if looks_like_number(value):
            raise NumberError(f"{value!r} is quoted text, not a number", want, example,
                              quoted=value.strip())
        raise NumberError(f"must be {want}, not the text {value!r}", want, example)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        shown = "null (nothing)" if value is None else repr(value)
        raise NumberError(f"must be {want}, not {shown}", want, example)
    if not math.isfinite(value):
        raise NumberError(f"must be finite, not {value!r}", want, example)
    if integer and isinstance(value, float):
        if value != int(value):
            raise NumberError(f"must be a whole number, not {value!r}", want, example)
        value = int(value)
    low = minimum is not None and (value <= minimum if strict_minimum else value < minimum)
    if low or (maximum is not None and value > maximum):
        raise NumberError(f"must be {want}, not {value!r}", want, example)
    return value


def is_number(value) -> bool:
    """An int or float, finite, not a bool (quoted numbers are text: False)."""
    try:
        read_number(value)
    except NumberError:
        return False
    return True


def _example(integer: bool, minimum, maximum, strict: bool) -> str:
    x = 1 if minimum is None else minimum + (1 if strict else 0)
    x = x if maximum is None else min(x, maximum)
    return f"{int(x)}" if integer else f"{x:g}"


# ---- YAML ---------------------------------------------------------------------------------------
class YamlLoader(yaml.SafeLoader):
    """SafeLoader with YAML 1.2 floats (`1e-3`, `1E5`: numbers, as OmegaConf reads them) that
    refuses a mapping key given twice (PyYAML silently keeps the last)."""

    def construct_mapping(self, node, deep=False):
        seen = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice (first on line {seen[key] + 1})",
                    key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


# the float resolver OmegaConf adds to its loader: exponents without a dot, YAML 1.2 style
YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
               |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
               |\.[0-9_]+(?:[eE][-+][0-9]+)?
               |[-+]?[0-9][0-9_]*(?::[0-5]?[0-9])+\.[0-9_]*
               |[-+]?\.(?:inf|Inf|INF)
               |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def load_yaml(text: str):
    """Parse YAML text with `YamlLoader` (safe: plain data only)."""
    return yaml.load(text, Loader=YamlLoader)  # noqa: S506  (YamlLoader is a SafeLoader)
