"""A sample's plain data as the text `mrta echo` prints: YAML (PyYAML's block style) or one
JSON line, written here rather than by yaml.safe_dump and json.dumps after a tidying pass.

Why: yaml.safe_dump took 2–5 ms a sample on a loaded machine and a replay at full speed
printed one sample in six; these take a few percent of that (benchmarks/echo.py). The text is
the same as theirs — YAML as `yaml.safe_dump(v, sort_keys=False, default_flow_style=None)`
writes it but for how a few strings are quoted and for never wrapping a line at 80 columns (a
script greps a sample's line whole); JSON as `jsonsafe.dumps` writes it — for
JSON-like data: str keys; str, int, float, bool and None leaves. Anything else (a foreign
client's bytes, an integer key) goes to PyYAML / json and comes out the same as before.

Floats are written to 15 significant digits (jsonsafe.tidy: 51.62, not 51.620000000000005);
in JSON, NaN and Infinity (no JSON numbers) as strings, so every line parses.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import yaml

from .. import jsonsafe

# A string is written plain only when YAML reads it back as that same string: letters, digits,
# `_./-` and inner spaces, starting with a letter, `_` or `/`, and none of the words PyYAML
# resolves to a boolean or null. Anything else is single-quoted when that needs no escape (as
# PyYAML writes it), else double-quoted JSON — ASCII-escaped, so no control character reaches
# a terminal raw.
_PLAIN = re.compile(r"[A-Za-z_/](?:[A-Za-z0-9_./\- ]*[A-Za-z0-9_./\-])?")
_RESOLVED = re.compile(r"yes|Yes|YES|no|No|NO|true|True|TRUE|false|False|FALSE|on|On|ON|off|"
                       r"Off|OFF|null|Null|NULL")
_QUOTABLE = re.compile(r"[ -&(-~]*")  # printable ASCII but the single quote
_CACHE_MAX = 4096  # strings remembered (field names, frame ids): they come from the network
_yaml_strings: dict[str, str] = {}
_json_strings: dict[str, str] = {}


class _Unusual(Exception):
    """A value outside JSON-like data: left to PyYAML / json."""


def yaml_text(value: Any) -> str:
    """`value` as YAML without a trailing newline (see the module docstring)."""
    try:
        if type(value) is dict or type(value) is list:
            if _flowable(value):
                return _yaml_flow(value)
            lines: list[str] = []
            _yaml_block(value, 0, lines)
            return "\n".join(lines)
        return _yaml_scalar(value)
    except _Unusual:
        return yaml.safe_dump(jsonsafe.tidy_all(value), sort_keys=False,
                              default_flow_style=None).rstrip()


def json_text(value: Any, default=None) -> str:
    """`value` as one line of JSON, as jsonsafe.dumps(value, nonfinite=str, default) writes it."""
    try:
        return _json(value)
    except _Unusual:
        return jsonsafe.dumps(value, nonfinite=str, default=default)


def _tidy_repr(x: float) -> str:
    """repr(jsonsafe.tidy(x)). A repr of at most 16 characters (a point or an exponent among
    them) has at most 15 significant digits: it is its own tidy form, found without the
    formatting round trip — most floats on the bus."""
    text = repr(x)
    return text if len(text) <= 16 else repr(jsonsafe.tidy(x))


# --------------------------------------------------------------------------- YAML
def _yaml_scalar(v: Any) -> str:
    t = type(v)
    if t is float:
        if math.isfinite(v):
            text = _tidy_repr(v)
            return text.replace("e", ".0e", 1) if "e" in text and "." not in text else text
        return ".nan" if v != v else (".inf" if v > 0 else "-.inf")
    if t is str:
        text = _yaml_strings.get(v)
        if text is None:
            if _PLAIN.fullmatch(v) and not _RESOLVED.fullmatch(v):
                text = v
            else:
                text = f"'{v}'" if _QUOTABLE.fullmatch(v) else json.dumps(v)
            if len(_yaml_strings) < _CACHE_MAX:
                _yaml_strings[v] = text
        return text
    return _int_bool_null(v, t)


def _int_bool_null(v: Any, t: type) -> str:
    """The scalars YAML and JSON write alike; anything else is unusual."""
    if t is int:
        return str(v)
    if t is bool:
        return "true" if v else "false"
    if v is None:
        return "null"
    raise _Unusual


def _yaml_key(k: Any) -> str:
    if type(k) is not str:
        raise _Unusual
    return _yaml_scalar(k)


def _flowable(v: dict | list) -> bool:
    """PyYAML's default_flow_style=None: a collection whose items are all scalars is written in
    flow style (`[1, 2]`, `{x: 1}`), any other as a block."""
    for x in (v.values() if type(v) is dict else v):
        t = type(x)
        if t is dict or t is list:
            return False
    return True


def _yaml_flow(v: dict | list) -> str:
    if type(v) is dict:
        return "{" + ", ".join([k + _yaml_scalar(x) for k, x in zip(_yaml_keys(v), v.values())]) \
            + "}"
    return "[" + ", ".join(map(_yaml_scalar, v)) + "]"


_key_rows: dict[tuple, list[str]] = {}


def _yaml_keys(v: dict) -> list[str]:
    """`["x: ", "y: "]` for a mapping's keys: messages of one type repeat the same keys."""
    keys = tuple(v)
    row = _key_rows.get(keys)
    if row is None:
        row = [f"{_yaml_key(k)}: " for k in keys]
        if len(_key_rows) < _CACHE_MAX:
            _key_rows[keys] = row
    return row


def _yaml_block(v: dict | list, indent: int, lines: list[str]) -> None:
    pad = " " * indent
    if type(v) is dict:
        for k, x in v.items():
            key = _yaml_key(k)
            t = type(x)
            if t is not dict and t is not list:
                lines.append(f"{pad}{key}: {_yaml_scalar(x)}")
            elif _flowable(x):
                lines.append(f"{pad}{key}: {_yaml_flow(x)}")
            else:  # PyYAML does not indent a sequence under a mapping key
                lines.append(f"{pad}{key}:")
                _yaml_block(x, indent + 2 if t is dict else indent, lines)
        return
    for x in v:
        t = type(x)
        if t is not dict and t is not list:
            lines.append(f"{pad}- {_yaml_scalar(x)}")
        elif _flowable(x):
            lines.append(f"{pad}- {_yaml_flow(x)}")
        else:  # the item's first line follows the dash
            start = len(lines)
            _yaml_block(x, indent + 2, lines)
            lines[start] = f"{pad}- {lines[start][indent + 2:]}"


# --------------------------------------------------------------------------- JSON
def _json(v: Any) -> str:
    t = type(v)
    if t is float:
        return _tidy_repr(v) if math.isfinite(v) else f'"{v}"'
    if t is str:
        text = _json_strings.get(v)
        if text is None:
            text = json.dumps(v)
            if len(_json_strings) < _CACHE_MAX:
                _json_strings[v] = text
        return text
    if t is dict:
        return "{" + ", ".join(f"{_json_key(k)}: {_json(x)}" for k, x in v.items()) + "}"
    if t is list:
        return "[" + ", ".join(map(_json, v)) + "]"
    return _int_bool_null(v, t)


def _json_key(k: Any) -> str:
    if type(k) is not str:
        raise _Unusual
    return _json(k)
