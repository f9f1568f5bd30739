"""Dotted scene keys (`params.g`, `grid.shape`, `biofilm.0.radius`): one place for every rule about them.

A key names one value of a scene: `--set KEY=VALUE`, a study's `[set]`, `[sweep]`,
`[sample.ranges]`, a stability case's `set`, a calibration's `[estimate]` all use
the same spelling, parsed, set, traced back and named by the functions here:

* `parse_override`, `key_parts`, `set_key`: 'params.g=1e10' into raw TOML data;
  a bare parameter name means `params.<name>`, a number indexes a list of regions.
* `Origins`, `given_by`, `blame`: an error in an overridden value names the place
  that gave it (`--set`, a study file), not the scene file.
* `flatten`: nested TOML tables as dotted keys.
* `dimension`, `id_text`: a swept key's name in study.nc and a value's spelling
  in a case id (stable: resume relies on them).
* `field_of`, `all_keys`, `takes_integers`: the one walk over a schema (pydantic
  models) along a dotted key.
"""
from __future__ import annotations

import hashlib
import json
import re
import tomllib
import typing
from pathlib import Path
from typing import Any

from pydantic import BaseModel
from pydantic.fields import FieldInfo

from solver.problem import parameter_infos

from ..errors import BadInput
from .tomltext import float_literal

PARAMETER_NAMES = tuple(info.name for info in parameter_infos())
# Keys that exclude each other: setting one (an override, a swept value) removes the other.
EXCLUSIVE = {("time", "outputs"): "output_times", ("time", "output_times"): "outputs"}
# Names a swept key cannot take in study.nc: the dimensions of a run's own variables.
RESERVED_DIMS = frozenset({"time", "time_mechanics", "x", "y", "z", "x_node", "y_node", "z_node", "component",
                           "case", "bounds"})


def parse_override(text: str) -> tuple[str, Any]:
    """'params.g=1e10' -> ('params.g', 1e10); the value is TOML, or a bare string if it is not."""
    key, sep, raw = text.partition("=")
    key, raw = key.strip(), raw.strip()
    if not sep or not key:
        raise BadInput(f"expected KEY=VALUE, e.g. params.g=1e10 (got {text!r})", "--set")
    try:
        value = tomllib.loads(f"value = {raw}")["value"]
    except tomllib.TOMLDecodeError:
        value = raw  # e.g. model.consumption=zero-order
    except RecursionError:  # '[[[[...' nested deeper than the decoder recurses
        raise BadInput(f"the value of {key} is nested too deeply to be read", "--set") from None
    return key, value


def key_parts(key: str) -> list[str]:
    """Dotted key -> parts; a bare parameter name (g, r, ...) means params.<name>."""
    parts = key.split(".")
    if not all(p.strip() for p in parts):
        raise BadInput("empty part in a dotted key", key=key)
    return ["params", *parts] if len(parts) == 1 and parts[0] in PARAMETER_NAMES else parts


def set_key(data: dict, key: str, value: Any) -> None:
    """Set a dotted key in a scene's raw TOML data; `biofilm.0.radius` indexes a list of regions."""
    parts = key_parts(key)
    other = EXCLUSIVE.get(tuple(parts))
    if other and isinstance(data.get(parts[0]), dict):
        data[parts[0]].pop(other, None)
    node: Any = data
    for depth, part in enumerate(parts):
        last = depth == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit():
                raise BadInput(f"{'.'.join(parts[:depth])} is a list: give an index, e.g. "
                               f"{'.'.join(parts[:depth])}.0.{part}", key=key)
            index = int(part)
            if index >= len(node):
                raise BadInput(f"there is no {'.'.join(parts[:depth])}[{index}] ({len(node)} given)", key=key)
            if last:
                node[index] = value
            node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = value
            else:
                node = node.setdefault(part, {})
        else:
            raise BadInput(f"{'.'.join(parts[:depth])} is a value, not a table", key=key)


def apply_overrides(data: dict, overrides: list[str] | tuple[str, ...], file: str = "--set") -> list[tuple[str, Any]]:
    """Apply 'KEY=VALUE' strings to raw data in order; returns the parsed (key, value) pairs."""
    pairs = []
    for text in overrides:
        key, value = parse_override(text)
        try:
            set_key(data, key, value)
        except BadInput as error:
            raise error.within(file) from None
        pairs.append((key, value))
    return pairs


# Where overridden keys came from: dotted key -> (where it was given: "--set" or a study file, the key's prefix
# there, e.g. "set."), so that an error in an overridden value names the place that gave it, not the scene file.
Origins = dict[str, tuple[str, str]]


def given_by(keys, where: str | Path, prefix: str = "") -> Origins:
    """Origins of `keys` (dotted keys, or (key, value) pairs), all given at `where`."""
    return {(key if isinstance(key, str) else key[0]): (str(where), prefix) for key in keys}


def blame(error: BadInput, origins: Origins | None) -> BadInput:
    """`error` attributed to where the value at its key was given, if an override gave it (the last one wins);
    each of its other problems (`BadInput.more`) likewise."""
    if not origins:
        return error
    more = tuple(blame(other, origins) for other in error.more)
    if error.key:
        parts = [p for p in re.split(r"[.\[\]]+", error.key) if p]
        for key, (where, prefix) in reversed(list(origins.items())):
            try:
                given = key_parts(key)
            except BadInput:
                continue
            n = min(len(given), len(parts))
            if given[:n] == parts[:n]:
                return BadInput(error.problem, where, prefix + error.key, more)
    return BadInput(error.problem, error.file, error.key, more)


def flatten(table: dict, prefix: str = "") -> dict[str, Any]:
    """{'grid': {'shape': [..]}} -> {'grid.shape': [..]}: TOML dotted keys and quoted ones alike."""
    flat = {}
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, dict):
            flat.update(flatten(v, name))
        else:
            flat[name] = v
    return flat


def dimension(key: str) -> str:
    """Name of a swept key in study.nc: 'params.g' and 'g' -> 'g'; 'grid.shape' -> 'grid_shape'."""
    parts = key_parts(key)
    name = "_".join(parts[1:] if parts[0] == "params" else parts)
    return f"sweep_{name}" if name in RESERVED_DIMS else name


def id_text(value: Any) -> str:
    """A swept value in a case id: 1e8 -> '1e+08', 50 -> '50', [20, 20, 20] -> '20x20x20'."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = f"{value:g}" if float(f"{value:g}") == value else float_literal(value)
    elif isinstance(value, int):
        text = str(value)
    elif isinstance(value, (list, tuple)):
        text = "x".join(id_text(v) for v in value)
    elif isinstance(value, str):
        text = value
    else:
        text = hashlib.sha1(json.dumps(value, sort_keys=True).encode()).hexdigest()[:8]
    return re.sub(r"[^A-Za-z0-9.+-]", "-", text)


def submodels(annotation) -> list[type[BaseModel]]:
    """Pydantic models inside a type annotation (list[...], X | None, Annotated[Union[...]])."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found = []
    for arg in typing.get_args(annotation):
        found += submodels(arg)
    return found


def field_of(model: type[BaseModel], key: str) -> FieldInfo | None:
    """The schema's field a dotted key ends at (list indices skipped; the first region shape that has the
    key answers for a list of shapes), or None if the schema has no such key."""
    models, found = [model], None
    for part in key_parts(key):
        if part.isdigit():
            continue
        found = next((m.model_fields[part] for m in models if part in m.model_fields), None)
        if found is None:
            return None
        models = submodels(found.annotation)
    return found


def all_keys(model: type[BaseModel]) -> set[str]:
    """Every key name anywhere in a schema (for 'did you mean ...?')."""
    keys = set(model.model_fields)
    for info in model.model_fields.values():
        for sub in submodels(info.annotation):
            keys |= all_keys(sub)
    return keys


def takes_integers(model: type[BaseModel], key: str) -> bool:
    """True where the schema takes an integer at `key` (time.steps, mechanics.every, ...)."""
    found = field_of(model, key)
    if found is None:
        return False
    kinds = typing.get_args(found.annotation)
    return found.annotation is int or (int in kinds and float not in kinds)
