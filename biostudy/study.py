"""A study file (README, "Scene and study files"): a base scene and a sweep over dotted scene keys, expanded into cases.

::

    scene = "directional.toml"      # relative to the study file
    [set]                           # optional: overrides for every case (like --set)
    "grid.shape" = [10, 10, 10]
    [sweep]
    mode = "grid"                   # grid: every combination; zip: element-wise
    g = [1e8, 1e10]                 # a bare parameter name means params.<name>
    r = [50, 100]

Instead of ``[sweep]``, a ``[sample]`` table draws the cases from a design
(Sobol', Morris, Latin hypercube, Halton; `biostudy.designs`); their ids are
``s0001``, ``s0002``, ...

Every case is validated as a scene before anything runs, so a bad value in
the fourth case stops the study at once (exit 2) instead of after hours.
Case ids are built from the swept values (``g=1e+08_r=50``): stable across
runs (resume relies on them) and readable as file names.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator

from . import designs
from .errors import BadInput, InvalidAt, from_validation_error, read_toml
from .formatting import value_text
from .scene import (Origins, Scene, apply_overrides, given_by, key_parts, parse_override, read_scene_data,
                    scene_from_data, set_key)
from .tomltext import float_literal

RESERVED_DIMS = frozenset({"time", "x", "y", "z", "x_node", "y_node", "z_node", "component", "case"})


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


class Sweep(BaseModel):
    """Which scene keys vary and how they combine."""

    model_config = ConfigDict(extra="forbid", strict=True)
    mode: Literal["grid", "zip"] = Field("grid", description="grid: every combination; zip: element-wise")
    values: dict[str, list[Any]] = Field(description="swept dotted scene key -> its values")

    @model_validator(mode="before")
    @classmethod
    def _gather(cls, data: Any):
        if not isinstance(data, dict):
            return data
        data = dict(data)
        mode = data.pop("mode", "grid")
        values = flatten(data)
        if not values:
            raise InvalidAt("", "sweeps no key: add e.g. g = [1e8, 1e10]")
        for key, options in values.items():
            if not isinstance(options, list) or not options:
                raise InvalidAt(key, f"must be a non-empty list of values (got {value_text(options)})")
        return {"mode": mode, "values": values}

    @model_validator(mode="after")
    def _consistent(self):
        lengths = {key: len(v) for key, v in self.values.items()}
        first = next(iter(lengths))
        for key, options in self.values.items():
            if self.mode == "zip" and lengths[key] != lengths[first]:
                raise InvalidAt(key, f"has {lengths[key]} values but {first} has {lengths[first]} "
                                     f"(zip mode pairs them element-wise)")
            labels = [id_text(v) for v in options]
            repeated = next((v for v, n in zip(options, labels) if labels.count(n) > 1), None)
            if repeated is not None and self.mode == "grid":
                raise InvalidAt(key, f"lists {value_text(repeated)} twice")
        seen: dict[str, str] = {}
        for key in self.values:
            try:
                name = dimension(key)
            except BadInput as error:
                raise InvalidAt(key, error.problem) from None
            if name in seen:
                raise InvalidAt(key, f"is the same key as {seen[name]}")
            seen[name] = key
        return self


class FlatSet(BaseModel):
    """A model with a `set` table of overrides, which may be written as nested tables: read as dotted keys."""

    @model_validator(mode="before")
    @classmethod
    def _flatten_set(cls, data: Any):
        if isinstance(data, dict) and isinstance(data.get("set"), dict):
            data = {**data, "set": flatten(data["set"])}
        return data


@dataclass(frozen=True)
class Case:
    """One simulation of a study or catalogue: its id, its overrides of the base scene, its position.

    attrs: what its case file records about it besides the id (a catalogue case: its name and why).
    """

    id: str
    values: dict[str, Any]
    index: tuple[int, ...]
    attrs: dict[str, Any] = field(default_factory=dict)

    def overrides(self) -> dict[str, Any]:
        return dict(self.values)


class ManyCases(FlatSet):
    """What study files and stability catalogues share: many cases of one base scene."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field("", description="short name (default: the file's name without .toml)")
    description: str = Field("", description="one line shown by `biostudy scenes`")
    scene: str = Field(description="base scene file, relative to this file")
    set: dict[str, Any] = Field({}, description="overrides applied to every case (dotted keys, like --set)")

    def cases(self) -> list[Case]:
        """Every case, in the order they run and are recorded."""
        raise NotImplementedError

    def check(self, base_data: dict, scene_file: Path, path: Path) -> None:
        """Checks against the base scene before the cases are made (bad input: `BadInput`)."""


class Study(ManyCases):
    """Many cases of one base scene: a sweep over scene keys, or a sampling design."""

    model_config = ConfigDict(extra="forbid", strict=True)
    sweep: Sweep | None = None
    sample: designs.Sample | None = None
    _integral: dict[str, bool] = PrivateAttr(default_factory=dict)

    @model_validator(mode="after")
    def _one_design(self):
        if (self.sweep is None) == (self.sample is None):
            raise InvalidAt("sample" if self.sample else "sweep",
                            "give either [sweep] or [sample], not both" if self.sample
                            else "a study needs a [sweep] or a [sample] table")
        return self

    def check(self, base_data: dict, scene_file: Path, path: Path) -> None:
        if self.sample is not None:
            self._integral = designs.check_ranges(self.sample, base_data, scene_file, path)

    def cases(self) -> list[Case]:
        if self.sample is None:
            return expand(self.sweep)
        return [Case(designs.case_id(i), values, (i,)) for i, values in enumerate(self.sample.points(self._integral))]


def expand(sweep: Sweep) -> list[Case]:
    """All cases, in a fixed order (grid: last key fastest; zip: list order)."""
    keys = list(sweep.values)
    names = [dimension(k) for k in keys]
    lists = [sweep.values[k] for k in keys]
    if sweep.mode == "grid":
        positions = itertools.product(*(range(len(v)) for v in lists))
        combos = [(idx, tuple(v[i] for v, i in zip(lists, idx))) for idx in positions]
    else:
        combos = [((i,), values) for i, values in enumerate(zip(*lists))]
    cases = []
    for index, values in combos:
        case_id = "_".join(f"{n}={id_text(v)}" for n, v in zip(names, values))
        cases.append(Case(case_id, dict(zip(keys, values)), index))
    return cases


@dataclass
class Plan:
    """A validated study or catalogue: every case compiled to a `Scene`, nothing run yet."""

    file: Path
    spec: ManyCases  # the Study or Catalogue as read
    scene_file: Path
    base: Scene
    cases: list[Case]
    scenes: dict[str, Scene]
    fixed: dict[str, Any]  # [set] and --set overrides applied to every case

    @property
    def keys(self) -> list[str]:
        """The swept or sampled keys (a study)."""
        return list(self.spec.sweep.values) if self.spec.sweep else self.spec.sample.keys

    @property
    def mode(self) -> str:
        """grid, zip or sample (a study)."""
        return self.spec.sweep.mode if self.spec.sweep else "sample"


def base_scene(path: Path, scene: str, fixed_set: dict[str, Any], overrides=()) -> tuple[Path, dict, dict]:
    """The raw data of the base scene a study or catalogue file names, with its [set] and the --set
    overrides applied; returns (scene file, data, the overrides applied to every case)."""
    scene_file = path.parent / scene
    if not scene_file.is_file():
        raise BadInput(f"scene file {scene!r} not found (looked for {scene_file})", path, "scene")
    data = read_scene_data(scene_file)
    for key, value in fixed_set.items():
        try:
            set_key(data, key, value)
        except BadInput as error:
            raise BadInput(error.problem, path, f"set.{key}") from None
    return scene_file, data, {**fixed_set, **dict(apply_overrides(data, overrides))}


def case_scene(base_data: dict, values: dict[str, Any], scene_file: Path, path: Path, case_name: str,
               origins: Origins | None = None) -> Scene:
    """One case's validated scene: the base data with the case's values; errors name the case, and the
    study file unless an override (`origins`: --set, the study's [set]) gave the value at fault."""
    data = copy.deepcopy(base_data)
    try:
        for key, value in values.items():
            set_key(data, key, value)
        return scene_from_data(data, scene_file, {**(origins or {}), **given_by(values, path)})
    except BadInput as error:
        raise error.relocated(lambda file: path if file in (None, str(scene_file)) else file,
                              lambda key: ": ".join(filter(None, (f"case {case_name}", key)))) from None


def load_plan(path: str | Path, model: type[ManyCases], overrides: list[str] | tuple[str, ...] = (),
              wrong_kind: Callable[[dict], str] = lambda data: "") -> Plan:
    """Read a study or catalogue file, its base scene and every case; any bad input is a `BadInput`.

    wrong_kind(data) says why the file is not of this kind ("" if it is), before it is validated.
    """
    path = Path(path)
    data = read_toml(path)
    problem = wrong_kind(data)
    if problem:
        raise BadInput(problem, path)
    data.setdefault("name", path.stem)
    try:
        spec = model.model_validate(data)
    except ValidationError as error:
        raise from_validation_error(error, path, known_keys=model.model_fields) from None
    scene_file, base_data, fixed = base_scene(path, spec.scene, spec.set, overrides)
    origins = {**given_by(spec.set, path, "set."), **given_by(map(parse_override, overrides), "--set")}
    base = scene_from_data(base_data, scene_file, origins)
    spec.check(base_data, scene_file, path)
    cases = spec.cases()
    ids = [case.id for case in cases]
    repeated = next((i for i in ids if ids.count(i) > 1), None)
    if repeated:
        raise BadInput(f"case {repeated} comes twice", path, "sweep" if isinstance(spec, Study) else "case")
    scenes = {case.id: case_scene(base_data, case.values, scene_file, path, case.attrs.get("case_id", case.id),
                                  origins) for case in cases}
    return Plan(path, spec, scene_file, base, cases, scenes, fixed)


def load_study(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Plan:
    """Read a study file, its base scene and every case; any bad input is a `BadInput`."""
    return load_plan(path, Study, overrides, lambda data: "this is a scene file (it has [grid]); run it with "
                     "`biostudy run`" if "grid" in data and "scene" not in data else "")
