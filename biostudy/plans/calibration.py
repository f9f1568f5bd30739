"""A calibration file (README, "Calibration"): a base scene, a measurement table, the keys to estimate and how.

::

    scene = "agar2d.toml"            # relative to this file; [set] as for studies
    [set]
    "time.steps" = 200
    [data]
    measurements = "agar.tsv"        # PEtab's measurement-table columns (`inputs.measurements`)
    time_unit = "h"                  # the table's times: any unit of time pint reads
    t_ref = "48 h"                   # the real time of T* = 1
    [estimate]                       # any real-valued scene key: [low, high] or [low, high, "log"]
    g = [1e7, 1e10, "log"]
    r = [20.0, 400.0, "log"]
    [conditions.half]                # optional: scene overrides of one simulationConditionId
    "nutrient.0.value" = 0.5
    [conditions.half.estimate]       # optional: keys this condition estimates for itself alone
    r = [20.0, 400.0, "log"]
    [method]
    name = "least-squares"           # or "posterior": samples on a GP surrogate (design, held_out, walkers, ...)
    starts = 4                       # multi-start from a Latin hypercube inside the bounds
    profiles = true                  # a profile likelihood per parameter (95 % intervals)

Without `[conditions]` every measurement is of the scene itself (an empty
`simulationConditionId`).  An estimated key is shared by every condition
unless a condition estimates it itself, then that condition has its own
parameter (named ``r[half]``).  Everything is checked before anything runs:
both ends of every bound by the scene's own schema (as a study's sample
ranges, `designs.check_ends`), each condition's scene, every row of the table
(its observable, its condition, its time within the run), each problem one
line (`BadInput`).  `CalibrationPlan.scene_at` makes the scene of one
simulation: a condition at given parameter values, its outputs at that
condition's measurement times.
"""
from __future__ import annotations

import copy
import difflib
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from ..inputs.keys import dimension, field_of, flatten, key_parts, set_key, takes_integers
from ..inputs.measurements import Measurement, read_measurements
from ..inputs.real_time import check_agree, in_t_star
from ..inputs.scene import SCENE_KEYS, Scene
from ..quantities import observables
from .cases import Case, ManyCases, Plan, base_scene, case_scene, load_plan
from .designs import Range, check_ends, parse_range

SCENE = "scene"  # the condition of a calibration without [conditions]
METHODS = ("least-squares", "posterior")


def _ranges(table: Any, where: str) -> dict[str, Range]:
    if not isinstance(table, dict):
        raise InvalidAt(where, f"must be a table of keys and [low, high] bounds (got {value_text(table)})")
    return {key: parse_range(key, given, where) for key, given in flatten(table).items()}


class DataSpec(BaseModel):
    """The measurements: the table and the unit of its times."""

    model_config = ConfigDict(extra="forbid", strict=True)
    measurements: str = Field(description="measurement table (CSV or TSV, PEtab's columns), relative to this file")
    time_unit: str | None = Field(None, description="unit of the table's times, e.g. \"h\", \"min\", \"d\" "
                                                     "(absent: the times are T*)")
    t_ref: str | None = Field(None, description="the real time of T* = 1, e.g. \"48 h\"")

    @model_validator(mode="after")
    def _both(self):
        if (self.time_unit is None) != (self.t_ref is None):
            raise InvalidAt("t_ref" if self.t_ref is None else "time_unit",
                            "give both time_unit and t_ref (the real time of T* = 1), or neither (times in T*)")
        return self

    def time_factor(self) -> float:
        """T* per unit of the table's time: t / t_ref with pint (`inputs.real_time`); `InvalidAt` for a unit
        that is not a time."""
        if self.time_unit is None or self.t_ref is None:
            return 1.0
        return in_t_star(self.time_unit, self.t_ref)


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


POSTERIOR_KEYS = ("design", "held_out", "walkers", "steps", "box")  # [method] keys of "posterior" alone


class MethodSpec(BaseModel):
    """How the parameters are estimated."""

    model_config = ConfigDict(extra="forbid", strict=True)
    name: Literal[METHODS] = Field("least-squares", description="least-squares: weighted least squares, "
                                   "multi-start, profile likelihoods; posterior: least squares, then samples of "
                                   "the posterior on a Gaussian-process surrogate")
    starts: int = Field(4, ge=1, le=64, description="starts of the optimiser, from a Latin hypercube in the bounds")
    profiles: bool = Field(True, description="a profile likelihood per parameter: its 95 % interval (posterior: "
                                             "false unless set)")
    seed: int = Field(0, ge=0, description="seed of the starts' design (posterior: of its design and chains too)")
    design: int = Field(30, ge=4, le=2000, description="posterior: simulations of the surrogate's training design "
                                                       "(the least-squares fit's own join them)")
    held_out: int = Field(8, ge=1, le=500, description="posterior: simulations held out to measure the surrogate's "
                                                       "error")
    walkers: int = Field(16, ge=4, le=1000, description="posterior: emcee's walkers (at least twice the parameters)")
    steps: int = Field(2000, ge=100, le=1_000_000, description="posterior: steps of every walker")
    box: float = Field(6.0, ge=2.0, le=1e6, description="posterior: the surrogate's box, the least-squares "
                                                         "estimate ± this many standard errors (within the bounds)")

    @model_validator(mode="after")
    def _keys_of_the_method(self):
        if self.name != "posterior":
            given = [key for key in POSTERIOR_KEYS if key in self.model_fields_set]
            if given:
                raise InvalidAt(given[0], f"applies to name = \"posterior\" only (this method is {self.name!r})")
        elif "profiles" not in self.model_fields_set:
            self.profiles = False
        return self


class Calibration(ManyCases):
    """A base scene, measurements, the keys to estimate (shared or per condition), and the method."""

    model_config = ConfigDict(extra="forbid")
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
        if self.method.name == "posterior":
            k = len(self.varied_keys_with_conditions())
            if self.method.walkers < 2 * k:
                raise InvalidAt("method.walkers", f"emcee needs at least twice as many walkers as parameters: "
                                                  f"{self.method.walkers} < 2 x {k}")
            if self.method.design < k + 2:
                raise InvalidAt("method.design", f"a surrogate of {k} parameters needs at least {k + 2} training runs "
                                                 f"(got {self.method.design})")
        for name in self.conditions:
            if not name or name != name.strip():
                raise InvalidAt(f"conditions.{name}", "a condition needs a name without surrounding spaces")
        return self

    def condition_names(self) -> list[str]:
        return list(self.conditions) or [SCENE]

    def cases(self) -> list[Case]:
        """One case per condition, at the scene's own values of the estimated keys: validated before anything
        runs."""
        return [Case(name, dict(self.conditions[name].set) if name in self.conditions else {}, (i,),
                     {"case_id": f"condition {name}"}) for i, name in enumerate(self.condition_names())]

    def varied_keys(self) -> list[str]:
        return list(dict.fromkeys([*self.estimate, *(k for c in self.conditions.values() for k in c.estimate)]))

    def varied_keys_with_conditions(self) -> list[str]:
        """One entry per estimated parameter (a key estimated per condition counts once per condition)."""
        return [*self.estimate, *(f"{k}[{n}]" for n, c in self.conditions.items() for k in c.estimate)]

    def case_noun(self) -> str:
        return "conditions"

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
            estimated = {_spelled(k) for k in (*self.estimate, *condition.estimate)}
            problems += [BadInput(f"sets {key}, which is estimated", path, f"conditions.{name}.{key}")
                         for key in condition.set if _spelled(key) in estimated]
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
        shared = [k for k in self.estimate
                  if self.conditions and all(k in c.estimate for c in self.conditions.values())]
        problems += [BadInput("every condition estimates it for itself: leave it out of [estimate]", path,
                              f"estimate.{key}") for key in shared]
        if problems:
            raise BadInput(problems[0].problem, problems[0].file, problems[0].key, tuple(problems[1:]))


def _spelled(key: str) -> tuple[str, ...]:
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


@dataclass(frozen=True)
class Parameter:
    """One estimated parameter: its name (the key's, with the condition for one of its own: r[half]), the scene key,
    its bounds, and the conditions it sets."""

    name: str
    key: str
    range: Range
    conditions: tuple[str, ...]

    @property
    def log(self) -> bool:
        return self.range.scale == "log"

    def value(self, unit: float) -> float:
        """The value at a point of [0, 1] of the bounds (log10 for log bounds); the bounds themselves exactly."""
        if unit <= 0.0:
            return self.range.low
        if unit >= 1.0:
            return self.range.high
        return float(self.range.values(np.array(float(unit))))


@dataclass
class CalibrationPlan:
    """A validated calibration: the conditions' scenes, the parameters, the measurements in T*; nothing run yet."""

    file: Path
    spec: Calibration
    plan: Plan  # one case per condition (at the scene's values)
    base_data: dict  # the base scene's raw data with [set] and --set applied
    parameters: list[Parameter]
    measurements: list[Measurement]
    times: np.ndarray  # T* of every measurement, in the table's order
    data_file: Path

    @property
    def conditions(self) -> list[str]:
        return self.spec.condition_names()

    def output_times(self, condition: str) -> list[float]:
        """The outputs of a condition's runs: its measurement times (T*)."""
        return sorted({float(t) for m, t in zip(self.measurements, self.times) if _condition(m) == condition})

    def values(self, unit: np.ndarray) -> dict[str, float]:
        """Parameter values (name -> value) at a point of the unit cube of the bounds (log10 for log bounds)."""
        return {p.name: p.value(u) for p, u in zip(self.parameters, unit)}

    def overrides(self, condition: str, values: dict[str, float]) -> dict[str, Any]:
        """What a simulation of `condition` at `values` sets: the condition's overrides, its parameters, its
        output times."""
        given = dict(self.spec.conditions[condition].set) if condition in self.spec.conditions else {}
        given.update({p.key: values[p.name] for p in self.parameters if condition in p.conditions})
        given["time.output_times"] = self.output_times(condition)
        return given

    def scene_at(self, condition: str, values: dict[str, float]) -> Scene:
        """The validated scene of one simulation (bounds were checked: a value inside them is valid)."""
        return case_scene(self.base_data, self.overrides(condition, values), self.plan.scene_file, self.file,
                          condition)


def _condition(measurement: Measurement) -> str:
    return measurement.condition or SCENE


def _parameters(spec: Calibration) -> list[Parameter]:
    names = spec.condition_names()
    found = []
    for key, rng in spec.estimate.items():
        sharing = tuple(n for n in names if key not in (spec.conditions[n].estimate if n in spec.conditions else {}))
        found.append(Parameter(dimension(key), key, rng, sharing))
    for name, condition in spec.conditions.items():
        found += [Parameter(f"{dimension(key)}[{name}]", key, rng, (name,)) for key, rng in condition.estimate.items()]
    return found


def _measurements(spec: Calibration, plan: Plan, path: Path) -> tuple[Path, list[Measurement], np.ndarray]:
    """The table, read and checked against the conditions' scenes; every problem at once."""
    data_file = path.parent / spec.data.measurements
    try:
        factor = spec.data.time_factor()
        for scene in plan.scenes.values():  # one clock: the table's t_ref is the scene's
            check_agree(spec.data.t_ref, scene.time.t_ref, plan.scene_file.name)
    except InvalidAt as error:
        raise BadInput(error.problem, path, f"data.{error.key}") from None
    rows = read_measurements(data_file)
    unit = f" {spec.data.time_unit}" if spec.data.time_unit else ""
    known = ", ".join(observables.REGISTRY)
    problems, times = [], np.array([m.time * factor for m in rows])
    for m, t in zip(rows, times):
        condition = _condition(m)
        if spec.conditions and not m.condition:
            problems.append(BadInput(f"empty; the calibration has conditions {', '.join(spec.conditions)}", data_file,
                                     f"line {m.line}: simulationConditionId"))
            continue
        if condition not in plan.scenes:
            what = (f"conditions are {', '.join(spec.conditions)}" if spec.conditions
                    else "the calibration has no [conditions]: leave it empty")
            problems.append(BadInput(f"unknown condition {m.condition!r} ({what})", data_file,
                                     f"line {m.line}: simulationConditionId"))
            continue
        scene = plan.scenes[condition]
        try:
            observable = observables.get(m.observable)
        except ValueError:
            close = difflib.get_close_matches(m.observable, list(observables.REGISTRY), n=1)
            problems.append(BadInput(f"unknown observable {m.observable!r}" + (f" (did you mean '{close[0]}'?)"
                                     if close else f"; observables are {known}"), data_file, f"line {m.line}: "
                                     "observableId"))
            continue
        if "p" in observable.needs and scene.mechanics is None:
            problems.append(BadInput(f"{m.observable} needs the mechanics, which the scene leaves out", data_file,
                                     f"line {m.line}: observableId"))
        t_end = scene.time.t_end
        if not 0 <= t <= t_end * (1 + 1e-12):
            when = "before the start" if t < 0 else "after the run's end"
            reference = f" (t_ref = {spec.data.t_ref})" if spec.data.t_ref else ""
            problems.append(BadInput(f"{value_text(m.time)}{unit} is T* = {t:.4g}{reference}, {when}: the scene "
                                     f"runs over T* = 0 to {value_text(t_end)} (time.t_end)", data_file,
                                     f"line {m.line}: time"))
    named = {m.condition for m in rows}
    problems += [BadInput("no row of the measurement table names it (simulationConditionId): nothing to fit", path,
                          f"conditions.{name}") for name in spec.conditions if name not in named]
    if problems:
        raise BadInput(problems[0].problem, problems[0].file, problems[0].key, tuple(problems[1:]))
    return data_file, rows, np.minimum(times, [plan.scenes[_condition(m)].time.t_end for m in rows])


def load_calibration(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                     runs_here: bool = False) -> CalibrationPlan:
    """Read a calibration file, its base scene, every condition and the measurement table; any bad input is a
    `BadInput` (every problem of the table at once; `runs_here`: as for `load_plan`)."""
    path = Path(path)
    plan = load_plan(path, Calibration, overrides, _wrong_kind, runs_here)
    spec = plan.spec
    assert isinstance(spec, Calibration)
    _, base_data, _ = base_scene(path, spec.scene, spec.set, overrides)
    data_file, rows, times = _measurements(spec, plan, path)
    return CalibrationPlan(path, spec, plan, base_data, _parameters(spec), rows, times, data_file)


def _wrong_kind(data: dict) -> str:
    if "grid" in data and "scene" not in data:
        return "this is a scene file (it has [grid]); a calibration names its scene (scene = ...)"
    if "sweep" in data or "sample" in data:
        return "this is a study file (it has [sweep] or [sample]); run it with `biostudy sweep`"
    if "data" not in data:
        return "a calibration file needs a [data] table (measurements = \"FILE.tsv\", time_unit, t_ref)"
    return ""
