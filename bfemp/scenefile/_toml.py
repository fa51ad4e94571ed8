"""A small TOML 1.0 writer for the plain data of scene files (reading is ``tomllib``'s job).

Values: ``bool``, ``int``, ``float`` (shortest ``repr``, which reads back to the same float64;
``inf``, ``-inf``, ``nan``), ``str`` (basic strings with escapes), lists of values (inline
arrays; long ones wrapped one item per line) and ``dict`` (tables). A table is written as::

    key = value            # its plain values first, in insertion order
    [parent.child]         # then each sub-table
    [[parent.items]]       # and each list of tables, one header per element

so nesting of any depth is expressed with headers (a sub-table of an element of an array of
tables is written after that element's header, which TOML attaches to the last element).
Lists that mix tables and plain values, and ``None`` values, cannot be written and raise
``ValueError`` naming the key.
"""

from __future__ import annotations

import math
import re

__all__ = ["dumps"]

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
_WRAP = 96  # inline arrays longer than this many characters are written one item per line
_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f"}
_ESCAPES["\r"] = "\\r"
#: ``str.translate`` table of basic strings: the escapes above, ``\\uXXXX`` for other controls
_TRANSLATE = {c: f"\\u{c:04x}" for c in (*range(0x20), 0x7F)} | {
    ord(k): v for k, v in _ESCAPES.items()
}


def _key(key: object) -> str:
    if not isinstance(key, str):
        raise ValueError(f"TOML keys must be strings, got {key!r}")
    return key if _BARE_KEY.fullmatch(key) else _string(key)


def _string(text: str) -> str:
    return '"' + text.translate(_TRANSLATE) + '"'


def _float(value: float) -> str:
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    text = repr(value)
    # TOML floats need a fraction or an exponent: 1e+20 is fine, but 100 would read as int.
    return text if any(c in text for c in ".en") else text + ".0"


def _is_table_list(value: object) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _value(value: object, where: str, indent: str = "") -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _float(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, dict):
        items = ", ".join(f"{_key(k)} = {_value(v, f'{where}.{k}')}" for k, v in value.items())
        return "{ " + items + " }" if items else "{}"
    if isinstance(value, list | tuple):
        items = [_value(v, f"{where}[{i}]", indent + "  ") for i, v in enumerate(value)]
        flat = "[" + ", ".join(items) + "]"
        if len(flat) <= _WRAP and "\n" not in flat:
            return flat
        inner = indent + "  "
        return "[\n" + "".join(f"{inner}{item},\n" for item in items) + indent + "]"
    raise ValueError(f"{where}: cannot write {type(value).__name__} value {value!r} to TOML")


def _table(lines: list[str], path: list[str], table: dict, header: str | None) -> None:
    if header is not None:
        if lines:
            lines.append("")
        lines.append(header)
    subtables = []
    for key, value in table.items():
        where = ".".join([*path, str(key)])
        if value is None:
            raise ValueError(f"{where}: TOML has no null value; leave the key out")
        if isinstance(value, dict) or _is_table_list(value):
            subtables.append((key, value))
            continue
        if isinstance(value, list) and any(isinstance(v, dict) for v in value):
            raise ValueError(f"{where}: a list mixing tables and plain values cannot be written")
        lines.append(f"{_key(key)} = {_value(value, where)}")
    for key, value in subtables:
        sub = [*path, _key(key)]
        dotted = ".".join(sub)
        if isinstance(value, dict):
            _table(lines, sub, value, f"[{dotted}]")
        else:
            for element in value:
                _table(lines, sub, element, f"[[{dotted}]]")


def dumps(data: dict, *, header_comment: str | None = None) -> str:
    """TOML text of a nested dict (see the module docstring for what can be written).

    Args:
        data: the document: str keys, values as above.
        header_comment: optional text written as ``#`` comment lines at the top.

    Returns:
        the TOML text, ending with a newline; ``tomllib.loads`` of it equals ``data`` (tuples
        read back as lists).
    """
    if not isinstance(data, dict):
        raise ValueError(f"a TOML document must be a dict, got {type(data).__name__}")
    lines: list[str] = []
    if header_comment:
        lines += [f"# {line}".rstrip() for line in header_comment.splitlines()]
    _table(lines, [], data, None)
    return "\n".join(lines) + "\n"
