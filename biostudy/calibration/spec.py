"""A calibration file's schema (docs/calibrate.md): its base scene and [set], [data], the keys to estimate, shared
or per condition ([conditions]), and [method] (`method_spec`); checked against the base scene's data (`check`).

A key estimated in [estimate] is shared by every condition unless a condition estimates it itself, then that
condition has its own parameter (named ``r[half]``); both ends of every bound are checked by the scene's own
schema (as a study's sample ranges, `designs.check_ends`), each problem one line (`BadInput`).
"""
from __future__ import annotations

import copy
import difflib
import typing
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from ..inputs.keys import field_of, flatten, id_text, key_parts, set_key, takes_integers
from ..inputs.scene import SCENE_KEYS, Scene
from ..plans.cases import Case, OnScene
from ..plans.designs import Range, check_ends, parse_range
from .method_spec import MethodSpec
from .methods import chosen
from .table import DataSpec

SCENE = "scene"  # the condition of a calibration without [conditions]


def _ranges(table: Any, where: str) -> dict[str, Range]:
    """The bounds of a table of estimated keys; a key given twice under two spellings (g, params.g) is
    `InvalidAt`, as in a study's [sample]."""
    if not isinstance(table, dict):
        raise InvalidAt(where, f"must be a table of keys and [low, high] bounds (got {value_text(table)})")
    ranges = {key: parse_range(key, given, where) for key, given in flatten(table).items()}
    seen: dict[tuple[str, ...], str] = {}
    for key in ranges:
        twin = seen.setdefault(spelled(key), key)
        if twin != key:
            raise InvalidAt(f"{where}.{key}", f"is the same key as {twin}")
    return ranges


class Condition(BaseModel):
    """One simulationConditionId: overrides of the scene, and the keys it estimates for itself."""

    model_config = ConfigDict(extra="forbid")
    set: dict[str, Any] = Field({}, description="scene overrides (dotted keys, as in [set])")
    estimate: dict[str, Range] = Field({}, description="keys estimated for this condition alone")

    @model_validator(mode="before")
    @classmethod
    def _split(cls, data: Any):
        if not isinstance(data, dict):
            raise InvalidAt("", f"must be a table of scene overrides (got {value_text(data)})")
        data = dict(data)
        estimate = data.pop("estimate", {})
        return {"set": flatten(data), "estimate": _ranges(estimate, "estimate")}


class Calibration(OnScene):
    """A base scene, measurements, the keys to estimate (shared or per condition), and the method."""

    data: DataSpec
    estimate: dict[str, Range] = Field({}, description="estimated dotted scene key -> [low, high] or [low, high, "
                                                       "\"log\"], shared by every condition")
    conditions: dict[str, Condition] = Field({}, description="simulationConditionId -> scene overrides")
    method: MethodSpec = Field(default_factory=MethodSpec)

    @model_validator(mode="before")
    @classmethod
    def _estimate(cls, data: Any):
        if isinstance(data, dict) and "estimate" in data:
            data = {**data, "estimate": _ranges(data["estimate"], "estimate")}
        return data

    @model_validator(mode="after")
    def _something_estimated(self):
        if not self.estimate and not any(c.estimate for c in self.conditions.values()):
            raise InvalidAt("estimate", "estimates no key: add e.g. g = [1e7, 1e10, \"log\"]")
        for key, problem in chosen(self.method).problems(len(self.parameter_names())):
            raise InvalidAt(f"method.{key}", problem)
        for name in self.conditions:
            if not name or name != name.strip():
                raise InvalidAt(f"conditions.{name}", "a condition needs a name without surrounding spaces")
        labels: dict[str, str] = {}
        for name in self.conditions:
            twin = labels.setdefault(label(name), name)
            if twin != name:
                raise InvalidAt(f"conditions.{name}", f"conditions {twin} and {name} collide as file names: both "
                                f"are {label(name)} in a case id (a case id keeps letters, digits and . _ + -; "
                                "others become -)")
        return self

    def condition_names(self) -> list[str]:
        return list(self.conditions) or [SCENE]

    def condition_cases(self) -> list[Case]:
        """One case per condition, at the scene's own values of the estimated keys: validated before anything
        runs."""
        return [Case(name, dict(self.conditions[name].set) if name in self.conditions else {}, (i,),
                     {"case_id": f"condition {name}"}) for i, name in enumerate(self.condition_names())]

    def estimated_keys(self) -> list[str]:
        """Every estimated scene key, once."""
        return list(dict.fromkeys([*self.estimate, *(k for c in self.conditions.values() for k in c.estimate)]))

    def parameter_names(self) -> list[str]:
        """One entry per estimated parameter (a key estimated per condition counts once per condition)."""
        return [*self.estimate, *(f"{k}[{n}]" for n, c in self.conditions.items() for k in c.estimate)]

    def check(self, base_data: dict, scene_file: Path, path: Path) -> None:
        problems = []
        tables = [("estimate", self.estimate, base_data)]
        for name, condition in self.conditions.items():
            data = copy.deepcopy(base_data)
            for key, value in condition.set.items():
                try:
                    set_key(data, key, value)
                except BadInput as error:
                    problems.append(BadInput(error.problem, path, f"conditions.{name}.{key}"))
            tables.append((f"conditions.{name}.estimate", condition.estimate, data))
            estimated = {spelled(k) for k in (*self.estimate, *condition.estimate)}
            problems += [BadInput(f"sets {key}, which is estimated", path, f"conditions.{name}.{key}")
                         for key in condition.set if spelled(key) in estimated]
        for table, ranges, data in tables:
            for key in ranges:
                problem = _estimable(key)
                if problem:
                    problems.append(BadInput(problem, path, f"{table}.{key}"))
                    continue
                try:
                    check_ends({key: ranges[key]}, data, scene_file, path, table)
                except BadInput as error:
                    problems.append(error)
        shared = [k for k in self.estimate if self.conditions and all(
            spelled(k) in {spelled(own) for own in c.estimate} for c in self.conditions.values())]
        problems += [BadInput("every condition estimates it for itself: leave it out of [estimate]", path,
                              f"estimate.{key}") for key in shared]
        if problems:
            raise BadInput(problems[0].problem, problems[0].file, problems[0].key, tuple(problems[1:]))


def label(name: str) -> str:
    """A condition's name in case ids and file names: spelled as a sweep spells a text value (`id_text`: a
    path's / and every character but letters, digits and . + - become -), its underscores kept."""
    return "_".join(id_text(part) for part in name.split("_"))


def spelled(key: str) -> tuple[str, ...]:
    """A dotted key as the scene reads it (g and params.g are the same key)."""
    try:
        return tuple(key_parts(key))
    except BadInput:
        return (key,)


def _estimable(key: str) -> str:
    """'' if a dotted key names a real number of the scene, else why not."""
    try:
        parts = key_parts(key)
    except BadInput as error:
        return error.problem
    found = field_of(Scene, key)
    if found is None:
        close = difflib.get_close_matches(parts[-1], sorted(SCENE_KEYS), n=1)
        return f"the scene has no key {'.'.join(parts)}" + (f" (did you mean '{close[0]}'?)" if close else "")
    if takes_integers(Scene, key) or float not in (found.annotation, *typing.get_args(found.annotation)):
        return f"{'.'.join(parts)} is not a real number: only real-valued keys can be estimated"
    return ""
