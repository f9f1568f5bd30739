"""A scene's [time]: the model clock (steps over [0, t_end]), the output clock (snapshots), and what T* = 1 is in
real time (`t_ref`)."""
from __future__ import annotations

import numpy as np
from pydantic import BaseModel, Field, model_validator

from solver.problem import times_problem

from ..errors import InvalidAt
from .declared import CONFIG, unit_field
from .real_time import real_time
from .resources import DEFAULT_OUTPUTS


class Time(BaseModel):
    """The model clock (steps) and the output clock (snapshots)."""

    model_config = CONFIG
    t_end: float = unit_field(1.0, "end time, normalised time T*", "1", gt=0)
    steps: int = unit_field(1000, "nominal steps over [0, t_end]; failed steps are bisected", "1", ge=1)
    outputs: int | None = unit_field(None, f"evenly spaced snapshots, t = 0 and t_end included "
                                       f"(default {DEFAULT_OUTPUTS})", "1", ge=2)
    output_times: list[float] | None = unit_field(None, "explicit snapshot times within [0, t_end], increasing "
                                                    "(t_end is added if missing); instead of outputs", "1",
                                              min_length=1)
    t_ref: str | None = Field(None, description="the real time of T* = 1, any time pint reads (\"48 h\"): "
                                                "datasets then carry time_real in that unit (absent: T* only)")

    @model_validator(mode="after")
    def _clock(self):
        if self.t_ref is not None:
            real_time(self.t_ref)
        if self.outputs is not None and self.output_times is not None:
            raise InvalidAt("output_times", "give either outputs or output_times, not both")
        wrong = times_problem(self.output_times or [], self.t_end)  # the solver's rule
        if wrong:
            raise InvalidAt(f"output_times[{wrong[0]}]", wrong[1])
        return self

    def count(self) -> int:
        """How many snapshots, counted without building the list of times (a million outputs is bad input,
        not a million floats)."""
        if self.output_times is not None:
            return len(self.output_times) + (self.output_times[-1] != self.t_end)
        return self.outputs or DEFAULT_OUTPUTS

    def times(self) -> np.ndarray:
        if self.output_times is None:
            return np.linspace(0.0, self.t_end, self.outputs or DEFAULT_OUTPUTS)
        times = list(self.output_times)
        return np.array(times if times[-1] == self.t_end else [*times, self.t_end])
