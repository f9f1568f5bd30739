"""Sampling designs of a study (`[sample]`, docs/sensitivity.md): which cases to run.

::

    scene = "directional.toml"
    [sample]
    method = "sobol"        # sobol (Saltelli's scheme), morris, lhs, halton
    n = 64                  # base samples (sobol: n (2k + 2) cases, or n (k + 2) without
                            # second order; morris: n trajectories of k + 1 cases; lhs, halton: n)
    seed = 1
    [sample.ranges]         # any scene key (dotted as in [sweep]): [low, high] or [low, high, "log"]
    g = [1e8, 1e10, "log"]
    r = [50.0, 200.0]

The points come from SALib (Saltelli's extension of the Sobol' sequence,
Morris trajectories) and `scipy.stats.qmc` (Latin hypercube, scrambled
Halton), drawn in the unit cube and mapped onto each range, uniformly or
uniformly in log10.  Keys whose scene values are integers are rounded.
Sobol', Halton and Morris designs are nested in n for a fixed seed: raising n
keeps the first cases (same ids, same values), so a re-run only runs the new
ones.  A Latin hypercube is not: a new n is a new design.

A range is bad input if either end leaves the values the scene allows: both
ends are set into the base scene (after `[set]`) and validated by the scene's
own schema.
"""
from __future__ import annotations

import copy
import json
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from ..inputs.keys import dimension, flatten, set_key, takes_integers
from ..inputs.scene import Scene, scene_from_data

METHODS = ("sobol", "morris", "lhs", "halton")
SCALES = ("linear", "log")


@dataclass(frozen=True)
class Range:
    """The interval one key is sampled from; `log`: uniform in log10."""

    low: float
    high: float
    scale: str = "linear"

    def values(self, unit: np.ndarray) -> np.ndarray:
        """Points of the unit interval mapped onto the range."""
        if self.scale == "log":
            return 10.0 ** (math.log10(self.low) + unit * (math.log10(self.high) - math.log10(self.low)))
        return self.low + unit * (self.high - self.low)

    def unit(self, values: np.ndarray) -> np.ndarray:
        """The inverse of `values`: where in [0, 1] each value lies (log10 for a log range)."""
        values = np.asarray(values, dtype=float)
        if self.scale == "log":
            return (np.log10(values) - math.log10(self.low)) / (math.log10(self.high) - math.log10(self.low))
        return (values - self.low) / (self.high - self.low)

    def text(self) -> str:
        return f"[{value_text(self.low)}, {value_text(self.high)}{', log' if self.scale == 'log' else ''}]"


def parse_range(key: str, given: Any, table: str = "ranges") -> Range:
    """[low, high] or [low, high, "log"|"linear"] -> Range; anything else is `InvalidAt` the key (in `table`)."""
    where = f"{table}.{key}"
    if not isinstance(given, list) or len(given) not in (2, 3):
        raise InvalidAt(where, f"must be [low, high] or [low, high, \"log\"] (got {value_text(given)})")
    low, high, *scale = given
    for end, value in (("low", low), ("high", high)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InvalidAt(where, f"{end} end must be a finite number (got {value_text(value)})")
    scale = scale[0] if scale else "linear"
    if scale not in SCALES:
        raise InvalidAt(where, f"scale must be \"linear\" or \"log\" (got {value_text(scale)})")
    if not low < high:
        raise InvalidAt(where, f"low end {value_text(low)} must be below the high end {value_text(high)}")
    if scale == "log" and low <= 0:
        raise InvalidAt(where, f"a log range must lie above 0 (got [{value_text(low)}, {value_text(high)}])")
    return Range(float(low), float(high), scale)


class Sample(BaseModel):
    """A sampling design over scene keys (the `[sample]` table of a study)."""

    model_config = ConfigDict(extra="forbid", strict=True)
    method: Literal[METHODS] = Field(description="sobol: Saltelli's scheme for Sobol' indices; morris: "
                                                 "elementary-effect trajectories; lhs: Latin hypercube; halton: "
                                                 "scrambled Halton sequence")
    n: int = Field(ge=1, description="base samples (sobol), trajectories (morris) or points (lhs, halton)")
    seed: int = Field(0, ge=0, description="seed of the scrambling or random draws: same seed, same design")
    second_order: bool | None = Field(None, description="sobol only: cross-samples for second-order indices "
                                                        "(default true: n (2k + 2) cases; false: n (k + 2))")
    levels: int | None = Field(None, ge=2, description="morris only: grid levels of each range (default 4, even)")
    ranges: dict[str, Range] = Field(description="sampled dotted scene key -> [low, high] or [low, high, \"log\"]")

    @model_validator(mode="before")
    @classmethod
    def _ranges(cls, data: Any):
        if not isinstance(data, dict) or not isinstance(data.get("ranges"), dict):
            return data
        given = flatten(data["ranges"])
        if not given:
            raise InvalidAt("ranges", "samples no key: add e.g. g = [1e8, 1e10, \"log\"]")
        return {**data, "ranges": {key: parse_range(key, value) for key, value in given.items()}}

    @model_validator(mode="after")
    def _fits_the_method(self):
        k = len(self.ranges)
        if self.second_order is not None and self.method != "sobol":
            raise InvalidAt("second_order", f"applies to method = \"sobol\" only (method is {self.method!r})")
        if self.levels is not None and self.method != "morris":
            raise InvalidAt("levels", f"applies to method = \"morris\" only (method is {self.method!r})")
        if self.levels is not None and self.levels % 2:
            raise InvalidAt("levels", f"must be even (got {self.levels})")
        least = self.least_n()
        if self.n < least:
            raise InvalidAt("n", f"is too small for method = \"{self.method}\" with {k} keys: at least {least} "
                                 f"(got {self.n})")
        if self.method == "sobol" and self.n & (self.n - 1):
            raise InvalidAt("n", f"must be a power of 2 for method = \"sobol\" (the Sobol' sequence is balanced "
                                 f"only then; got {self.n}: take {1 << (self.n - 1).bit_length()})")
        seen: dict[str, str] = {}
        for key in self.ranges:
            try:
                name = dimension(key)
            except BadInput as error:
                raise InvalidAt(f"ranges.{key}", error.problem) from None
            if name in seen:
                raise InvalidAt(f"ranges.{key}", f"is the same key as {seen[name]}")
            seen[name] = key
        return self

    def least_n(self) -> int:
        """The smallest n the method's estimates can be made from (not the n they are good at)."""
        k = len(self.ranges)
        return {"sobol": 4, "morris": 2}.get(self.method, k + 2)  # lhs, halton: partial correlations need k + 2

    @property
    def keys(self) -> list[str]:
        return list(self.ranges)

    @property
    def with_second_order(self) -> bool:
        return self.method == "sobol" and self.second_order is not False

    @property
    def morris_levels(self) -> int:
        return self.levels or 4

    def block(self) -> int:
        """Cases per base sample: sobol 2k + 2 (k + 2 without second order), morris k + 1, else 1."""
        k = len(self.ranges)
        if self.method == "sobol":
            return 2 * k + 2 if self.with_second_order else k + 2
        return k + 1 if self.method == "morris" else 1

    def unit_problem(self) -> dict:
        """SALib's problem over the unit cube, one variable per sampled key (scaled to the ranges later)."""
        k = len(self.ranges)
        return {"num_vars": k, "names": [f"x{i}" for i in range(k)], "bounds": [[0.0, 1.0]] * k}

    def unit_points(self) -> np.ndarray:
        """The design in the unit cube, one row per case, in the order the cases run (SALib, scipy.stats.qmc)."""
        k = len(self.ranges)
        unit = self.unit_problem()
        if self.method == "sobol":
            from SALib.sample import sobol

            return sobol.sample(unit, self.n, calc_second_order=self.with_second_order, scramble=True,
                                seed=self.seed)
        if self.method == "morris":
            from SALib.sample import morris

            return morris.sample(unit, self.n, num_levels=self.morris_levels, seed=self.seed)
        from scipy.stats import qmc

        engine = (qmc.LatinHypercube if self.method == "lhs" else qmc.Halton)(d=k, scramble=True, rng=self.seed)
        with warnings.catch_warnings():  # Halton's balance warning concerns Sobol'-type sequences only
            warnings.simplefilter("ignore", UserWarning)
            return engine.random(self.n)

    def points(self) -> list[dict[str, Any]]:
        """Every case's values, key -> value on its range; rounded where the scene's schema takes integers."""
        unit = self.unit_points()
        columns = {}
        for j, (key, rng) in enumerate(self.ranges.items()):
            values = rng.values(unit[:, j])
            columns[key] = [int(round(v)) for v in values] if takes_integers(Scene, key) else values.tolist()
        return [{key: columns[key][i] for key in self.ranges} for i in range(unit.shape[0])]

    def attrs(self) -> dict[str, Any]:
        """What study.nc records of the design; `sample_design` (JSON) is read back by `from_attrs`."""
        design = {"method": self.method, "n": self.n, "seed": self.seed, "second_order": self.second_order,
                  "levels": self.levels, "ranges": {k: [r.low, r.high, r.scale] for k, r in self.ranges.items()}}
        return {"sample_method": self.method, "sample_n": self.n, "sample_seed": self.seed,
                "sample_cases_per_block": self.block(), "sample_keys": ", ".join(self.keys),
                "sample_ranges": "; ".join(f"{key} = {rng.text()}" for key, rng in self.ranges.items()),
                "sample_design": json.dumps(design)}


def from_attrs(attrs: dict) -> Sample | None:
    """The design recorded in a study.nc's attributes (None for a grid or zip sweep)."""
    if "sample_design" not in attrs:
        return None
    design = json.loads(str(attrs["sample_design"]))
    return Sample.model_validate({k: v for k, v in design.items() if v is not None})


def check_ranges(sample: Sample, base_data: dict, scene_file: Path, study_file: Path) -> None:
    """Both ends of every range set into the base scene and validated by the scene's schema.  A range that
    leaves the allowed values is `BadInput` naming `sample.ranges.KEY`."""
    check_ends(sample.ranges, base_data, scene_file, study_file, "sample.ranges")


def check_ends(ranges: dict[str, Range], base_data: dict, scene_file: Path, file: Path, table: str) -> None:
    """Both ends of every range set into the base scene and validated by the scene's schema; `BadInput` naming
    `table.KEY` for a range that leaves the allowed values (a study's sample ranges, a calibration's bounds)."""
    for key, rng in ranges.items():
        integral = takes_integers(Scene, key)
        for end, value in (("low", rng.low), ("high", rng.high)):
            data = copy.deepcopy(base_data)
            try:
                set_key(data, key, int(round(value)) if integral else value)
                scene_from_data(data, scene_file)
            except BadInput as error:
                where = f" ({error.key})" if error.key else ""
                raise BadInput(f"{end} end {value_text(value)} leaves the allowed values{where}: {error.problem}",
                               file, f"{table}.{key}") from None


def case_id(index: int) -> str:
    """s0001, s0002, ...: stable when n is raised (s10000 follows s9999)."""
    return f"s{index + 1:04d}"
