"""Scene data back to TOML text, the way a person writes it.

Covers what scenes and overrides hold: strings, booleans, numbers, arrays
of those, tables and arrays of tables.  Floats are written in their shortest
form that reads back exactly (1e+08, not 100000000.0), arrays on one line;
`tomllib.loads(dumps(data)) == data` for such data.
"""
from __future__ import annotations

import json
import math
import re

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def float_literal(value: float) -> str:
    """Shortest TOML float that reads back to `value` exactly."""
    if math.isnan(value):
        return "nan"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    plain = repr(float(value))
    short = next(s for s in (f"{value:.{p}g}" for p in range(1, 18)) if float(s) == value)
    if not any(ch in short for ch in ".e"):
        short += ".0"
    return short if len(short) < len(plain) else plain


def key(name: str) -> str:
    return name if _BARE.match(name) else json.dumps(name)


def literal(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return float_literal(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # a JSON string is a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(literal(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{key(k)} = {literal(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} as TOML")


def _is_tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def dumps(data: dict, _name: str = "") -> str:
    """TOML text of `data`: plain keys first, then [tables] and [[arrays of tables]]."""
    lines = [f"{key(k)} = {literal(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not _is_tables(v)]
    chunks = ["\n".join(lines)] if lines else []
    for k, v in data.items():
        name = f"{_name}.{key(k)}" if _name else key(k)
        if isinstance(v, dict):
            chunks.append(f"[{name}]\n" + dumps(v, name) if v else f"[{name}]")
        elif _is_tables(v):
            chunks += [f"[[{name}]]\n" + dumps(item, name) for item in v]
    return "\n\n".join(chunk.rstrip("\n") for chunk in chunks) + "\n"
