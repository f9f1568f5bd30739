"""The measurements of a calibration file: its [data] table (the measurement table and the unit of its times) and
what every row's numbers must be for a fit to compute with them (docs/calibration.md, "Choices")."""
from __future__ import annotations

import difflib
import functools

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..errors import InvalidAt
from ..formatting import value_text
from ..inputs.real_time import in_t_star
from ..quantities import observables
from .measurements import Measurement

EXTREME = 1e100  # the largest |measurement|, σ and |measurement| / σ (and 1 / it the smallest σ) a fit takes


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
        """T* per unit of the table's time: t / t_ref (`inputs.real_time`); `InvalidAt` for a unit that is not a
        time."""
        return 1.0 if self.time_unit is None or self.t_ref is None else in_t_star(self.time_unit, self.t_ref)


@functools.lru_cache(maxsize=64)
def unknown_observable(name: str) -> str:
    """Why `name` is no observable, with the closest one; cached: a table may misspell one name on every row
    (difflib took 16 s for 100,000 rows)."""
    close = difflib.get_close_matches(name, list(observables.REGISTRY), n=1)
    return f"unknown observable {name!r}" + (f" (did you mean '{close[0]}'?)" if close else
                                             f"; observables are {', '.join(observables.REGISTRY)}")


def extreme_numbers(m: Measurement) -> tuple[str, str] | None:
    """(column, why) for a row whose numbers a fit cannot compute with: its weighted residuals (model - value) / σ,
    their squares and their derivatives must stay far inside floating point (`EXTREME`); σ only where the table
    gives it (an estimated σ's rows are scaled by their root mean square)."""
    beyond = "beyond what a fit computes with"
    if m.noise:
        return ("measurement", f"{m.value!r} lies outside -{value_text(EXTREME)} to {value_text(EXTREME)}, "
                f"{beyond}") if not abs(m.value) <= EXTREME else None
    if not 1 / EXTREME <= m.sigma <= EXTREME:
        return "noiseParameters", (f"σ = {m.sigma!r} lies outside {value_text(1 / EXTREME)} to "
                                   f"{value_text(EXTREME)}, {beyond}: give σ in the measurement's units")
    if not abs(m.value) <= EXTREME:
        return "measurement", f"{m.value!r} lies outside -{value_text(EXTREME)} to {value_text(EXTREME)}, {beyond}"
    if not abs(m.value) / m.sigma <= EXTREME:
        return "noiseParameters", (f"the measurement is {abs(m.value) / m.sigma:.3g} σ from 0 (σ = {m.sigma!r}), "
                                   f"{beyond}: give σ in the measurement's units")
    return None
