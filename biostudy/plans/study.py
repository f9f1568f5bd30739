"""A study file (docs/scenes.md): a base scene and a sweep over dotted scene keys, expanded into cases.

::

    scene = "directional.toml"      # relative to the study file
    [set]                           # optional: overrides for every case (like --set)
    "grid.shape" = [10, 10, 10]
    [sweep]
    mode = "grid"                   # grid: every combination; zip: element-wise
    g = [1e8, 1e10]                 # a bare parameter name means params.<name>
    r = [50, 100]

Instead of ``[sweep]``, a ``[sample]`` table draws the cases from a design
(Sobol', Morris, Latin hypercube, Halton; `biostudy.plans.designs`); their ids
are ``s0001``, ``s0002``, ...

Case ids are built from the swept values (``g=1e+08_r=50``): stable across
runs (resume relies on them) and readable as file names.
"""
from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from ..inputs.keys import dimension, flatten, id_text
from ..inputs.resources import Preflight
from . import designs
from .cases import Case, ManyCases, Plan, load_plan


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
                twins = [v for v, n in zip(options, labels) if n == id_text(repeated)]
                if any(t != twins[0] for t in twins):
                    raise InvalidAt(key, f"lists {' and '.join(value_text(t) for t in twins[:2])}, which collide as "
                                         f"file names: both are {id_text(repeated)} in a case id (a case id keeps "
                                         "letters, digits and . + -; others become -)")
                raise InvalidAt(key, f"lists {value_text(repeated)} twice")
        seen: dict[str, str] = {}
        for key in self.values:
            try:
                name = dimension(key)
            except BadInput as error:
                raise InvalidAt(key, error.problem) from None
            if name in seen:
                raise InvalidAt(key, f"is the same key as {seen[name]}")
            if name == "time_t_ref":  # cases in different units would stack time_real under one unit
                raise InvalidAt(key, "is the real time of T* = 1, not a parameter: every case would be the same "
                                     "simulation; give it once in [set] (docs/time.md)")
            seen[name] = key
        return self


class Study(ManyCases):
    """Many cases of one base scene: a sweep over scene keys, or a sampling design."""

    model_config = ConfigDict(extra="forbid", strict=True)
    sweep: Sweep | None = None
    sample: designs.Sample | None = None

    @model_validator(mode="after")
    def _one_design(self):
        if (self.sweep is None) == (self.sample is None):
            raise InvalidAt("sample" if self.sample else "sweep",
                            "give either [sweep] or [sample], not both" if self.sample
                            else "a study needs a [sweep] or a [sample] table")
        return self

    def check(self, base_data: dict, scene_file: Path, path: Path) -> None:
        if self.sample is not None:
            designs.check_ranges(self.sample, base_data, scene_file, path)

    def cases(self) -> list[Case]:
        if self.sample is None:
            return expand(self.sweep)
        return [Case(designs.case_id(i), values, (i,)) for i, values in enumerate(self.sample.points())]

    def varied_keys(self) -> list[str]:
        return list(self.sweep.values) if self.sweep else self.sample.keys

    def layout(self) -> str:
        return self.sweep.mode if self.sweep else "sample"

    def case_noun(self) -> str:
        return "sweep" if self.sweep else "sample"


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


def load_study(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
               preflight: Preflight | None = None) -> Plan:
    """Read a study file, its base scene and every case; any bad input is a `BadInput` (`preflight`: as for
    `load_plan`)."""
    return load_plan(path, Study, overrides, lambda data: "this is a scene file (it has [grid]); run it with "
                     "`biostudy run`" if "grid" in data and "scene" not in data else "", preflight)
