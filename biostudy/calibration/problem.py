"""A calibration file read (docs/calibrate.md): a base scene, a measurement table, the keys to estimate and how;
its schema is `spec`'s, what it becomes a `CalibrationPlan` (the parameters: names, bounds, scales; the measurements
in T*; the noise parameters).

::

    scene = "agar2d.toml"            # relative to this file; [set] as for studies
    [set]
    "time.steps" = 200
    [data]
    measurements = "agar.tsv"        # PEtab's measurement-table columns (`measurements`)
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
    name = "least-squares"           # a method of `methods` (or samples of the posterior on a GP surrogate)
    starts = 4                       # multi-start from a Latin hypercube inside the bounds
    profiles = true                  # a profile likelihood per parameter (95 % intervals)

Without `[conditions]` every measurement is of the scene itself: its `simulationConditionId` empty, or one
name on every row (PEtab asks for one: that name is then the scene's condition, as an empty
`[conditions.NAME]`). An estimated key is shared by every condition unless a condition estimates it itself,
then that condition has its own parameter (named ``r[half]``). Everything is checked before anything runs:
both ends of every bound by the scene's own schema (as a study's sample ranges, `designs.check_ends`), each
condition's scene, every row of the table (its observable, its condition, its time within the run), each
problem one line (`BadInput`); σ named in `noiseParameters` is estimated (`noise`). `CalibrationPlan.scene_at`
makes the scene of one simulation: a condition at given parameter values, its outputs at that condition's
measurement times."""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from ..inputs.files import read_toml
from ..inputs.keys import dimension
from ..inputs.real_time import apart, check_agree, exact
from ..inputs.resources import Preflight
from ..inputs.scene import Scene
from ..plans.cases import case_scene, compile_cases, read_based
from ..plans.designs import Range
from ..quantities import observables
from .measurements import Measurement, read_measurements, refusal
from .methods import METHODS
from .noise import NoiseParameter, noise_parameters, noise_problems
from .petab_in import calibration_data
from .spec import SCENE, Calibration, Condition, label, spelled
from .table import extreme_numbers, unknown_observable


@dataclass(frozen=True)
class Parameter:
    """One estimated parameter: its name (the key's, with the condition for one of its own: r[half]), the scene key,
    its bounds, and the conditions it sets."""

    name: str
    key: str
    range: Range
    conditions: tuple[str, ...]
    label: str  # the name in case ids (a condition's own parameter: its condition's `label`)

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
    scene_file: Path
    base: Scene  # the base scene with [set] and --set applied
    scenes: dict[str, Scene]  # every condition's (at the scene's own values of the estimated keys)
    base_data: dict  # the base scene's raw data with [set] and --set applied
    parameters: list[Parameter]
    measurements: list[Measurement]
    times: np.ndarray  # T* of every measurement, in the table's order
    data_file: Path
    common: dict = field(default_factory=dict)  # the overrides of every simulation: [set], then --set

    @property
    def conditions(self) -> list[str]:
        return self.spec.condition_names()

    @functools.cached_property
    def noise(self) -> list[NoiseParameter]:
        """The σs the table names to estimate (`calibration_noise`)."""
        return noise_parameters(self.measurements)

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
        return case_scene(self.base_data, self.overrides(condition, values), self.scene_file, self.file, condition)


def _condition(measurement: Measurement) -> str:
    return measurement.condition or SCENE


def _parameters(spec: Calibration) -> list[Parameter]:
    names = spec.condition_names()
    found = []
    for key, rng in spec.estimate.items():
        own = {n: {spelled(k) for k in spec.conditions[n].estimate} for n in spec.conditions}
        sharing = tuple(n for n in names if spelled(key) not in own.get(n, set()))
        found.append(Parameter(dimension(key), key, rng, sharing, dimension(key)))
    for name, condition in spec.conditions.items():
        found += [Parameter(f"{dimension(key)}[{name}]", key, rng, (name,), f"{dimension(key)}[{label(name)}]")
                  for key, rng in condition.estimate.items()]
    return found


def _measurements(spec: Calibration, scenes: dict[str, Scene], scene_file: Path, path: Path,
                  rows: list[Measurement]) -> tuple[Path, list[Measurement], np.ndarray]:
    """The table's rows checked against the conditions' scenes; every problem at once."""
    data_file = path.parent / spec.data.measurements
    try:
        factor = spec.data.time_factor()
        for scene in scenes.values():  # one clock: the table's t_ref is the scene's
            check_agree(spec.data.t_ref, scene.time.t_ref, scene_file.name)
    except InvalidAt as error:
        raise BadInput(error.problem, path, f"data.{error.key}") from None
    unit = f" {spec.data.time_unit}" if spec.data.time_unit else ""
    problems, times = [], np.array([m.time * factor for m in rows])
    for m, t in zip(rows, times):
        condition = _condition(m)
        if spec.conditions and not m.condition:
            problems.append(BadInput(f"empty; the calibration has conditions {', '.join(spec.conditions)}", data_file,
                                     f"line {m.line}: simulationConditionId"))
            continue
        if condition not in scenes:
            what = (f"conditions are {', '.join(spec.conditions)}" if spec.conditions
                    else "the calibration has no [conditions]: leave it empty")
            problems.append(BadInput(f"unknown condition {m.condition!r} ({what})", data_file,
                                     f"line {m.line}: simulationConditionId"))
            continue
        extreme = extreme_numbers(m)
        if extreme:
            problems.append(BadInput(extreme[1], data_file, f"line {m.line}: {extreme[0]}"))
        scene = scenes[condition]
        try:
            observable = observables.get(m.observable)
        except ValueError:
            problems.append(BadInput(unknown_observable(m.observable), data_file, f"line {m.line}: observableId"))
            continue
        missing = ("needs the mechanics, which the scene leaves out" if "p" in observable.needs and scene.mechanics
                   is None else scene.substratum_found().why_none if observable.needs_attrs else "")
        if missing:
            problems.append(BadInput(f"{m.observable}: {missing}", data_file, f"line {m.line}: observableId"))
        t_end = scene.time.t_end
        if not 0 <= t <= t_end * (1 + 1e-12):
            when = "before the start" if t < 0 else "after the run's end"
            reference = f" (t_ref = {spec.data.t_ref})" if spec.data.t_ref else ""
            told = f"{exact(m.time)}{unit} is T* = {apart(t, t_end)}{reference}"
            problems.append(BadInput(f"{told}, {when}: the scene runs over T* = 0 to {exact(t_end)} "
                                     "(time.t_end)", data_file, f"line {m.line}: time"))
    problems += _runs_too_short(spec, rows, times, data_file, path)
    problems += noise_problems(rows, METHODS[spec.method.name], spec.parameter_names(), data_file, path)
    named = {m.condition for m in rows}
    problems += [BadInput("no row of the measurement table names it (simulationConditionId): nothing to fit", path,
                          f"conditions.{name}") for name in spec.conditions if name not in named]
    if problems:
        raise refusal(problems, data_file)
    return data_file, rows, np.minimum(times, [scenes[_condition(m)].time.t_end for m in rows])


def _runs_too_short(spec: Calibration, rows: list[Measurement], times: np.ndarray, data_file: Path,
                    path: Path) -> list[BadInput]:
    """A `BadInput` for every estimated time.t_end whose low end stops a run before its condition's last
    measurement: a simulation there could not be compared with it."""
    problems = []
    for p in _parameters(spec):
        if spelled(p.key) != ("time", "t_end"):
            continue
        measured = [(t, m.line) for m, t in zip(rows, times) if _condition(m) in p.conditions]
        if not measured:
            continue
        latest, line = max(measured)
        if p.range.low < latest:
            shared = p.name == dimension(p.key)
            where = f"estimate.{p.key}" if shared else f"conditions.{p.conditions[0]}.estimate.{p.key}"
            problems.append(BadInput(f"low end {value_text(p.range.low)} ends a run before the measurement at "
                                     f"T* = {latest:.4g} ({data_file.name}, line {line}): every run must reach "
                                     "the last measurement of its condition", path, where))
    return problems


PETAB_SUFFIXES = (".yaml", ".yml")  # a PEtab problem, read as the calibration file it describes (`petab_in`)


def _calibration_data(path: Path) -> dict:
    """A calibration file's data: TOML, or a PEtab problem.yaml (`petab_in.calibration_data`)."""
    return calibration_data(path) if path.suffix.lower() in PETAB_SUFFIXES else read_toml(path)


def load_calibration(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                     preflight: Preflight | None = None) -> CalibrationPlan:
    """Read a calibration file, its base scene, every condition and the measurement table; any bad input is a
    `BadInput` (every problem of the table at once; `preflight`: as for `cases.load_plan`)."""
    path = Path(path)
    based = read_based(path, Calibration, overrides, _wrong_kind, preflight, lambda spec: (
        spec.estimated_keys(), "estimated by this calibration ({key}), so every simulation would replace it; change "
                               "its bounds instead"), read=_calibration_data)
    spec, scene_file, base_data = based.spec, based.scene_file, based.data
    try:
        spec.data.time_factor()  # a unit that is no time before the table's rows
    except InvalidAt as error:
        raise BadInput(error.problem, path, f"data.{error.key}") from None
    rows = read_measurements(path.parent / spec.data.measurements)
    spec = _named_scene(spec, rows)
    scenes = compile_cases(spec.condition_cases(), base_data, scene_file, path, based.origins, preflight)
    data_file, rows, times = _measurements(spec, scenes, scene_file, path, rows)
    return CalibrationPlan(path, spec, scene_file, based.scene, scenes, base_data, _parameters(spec), rows, times,
                           data_file, based.common)


def _named_scene(spec: Calibration, rows: list[Measurement]) -> Calibration:
    """A calibration without [conditions] whose table names one condition (PEtab asks every row for one): that
    condition is the scene itself, as an empty [conditions.NAME] says."""
    named = {m.condition for m in rows if m.condition}
    if spec.conditions or len(named) != 1:
        return spec
    return spec.model_copy(update={"conditions": {named.pop(): Condition.model_validate({})}})


def _wrong_kind(data: dict) -> str:
    if "grid" in data and "scene" not in data:
        return "this is a scene file (it has [grid]); a calibration names its scene (scene = ...)"
    if "sweep" in data or "sample" in data:
        return "this is a study file (it has [sweep] or [sample]); run it with `biostudy sweep`"
    if "data" not in data:
        return "a calibration file needs a [data] table (measurements = \"FILE.tsv\", time_unit, t_ref)"
    return ""
