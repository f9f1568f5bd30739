"""Fields kept within their bounds: round-off projected onto a bound, anything beyond it a failed step.

A linear solve returns c or phi to within its tolerance, so a value can lie a
little outside a bound that the exact discrete solution keeps (0 <= c <= the
largest held value; 0 <= phi <= max(phi^n + dt k_alpha alpha^n)).  Within
`ROUNDOFF` of a bound it is projected onto the bound; beyond, the step fails
(`StepFailure`) and the clock bisects it.

`Projection` tallies what was projected over a run, so that the dataset can
say it (``projected_*`` attributes): how many values were moved and the
largest correction.  Corrections far below ROUNDOFF are solver round-off; a
largest correction close to ROUNDOFF means the raw solutions are drifting
toward a bound.  The tally covers every attempted step, also steps that were
then bisected or rejected by the error control.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..counters import Counters
from ..errors import StepFailure

ROUNDOFF = 1e-8  # relative distance to a bound that counts as round-off


@dataclass
class Projection:
    """How many values were projected onto their bounds, and the largest correction."""

    count: int = 0
    largest: float = 0.0

    def counters(self, name: str) -> Counters:
        return {f"projected_{name}_count": self.count,
                f"projected_{name}_largest": self.largest}

    def onto(self, values: np.ndarray, lower: float, upper: float) -> np.ndarray:
        """`values` clipped to [lower, upper]; the correction is tallied."""
        clipped = np.clip(values, lower, upper)
        moved = np.abs(clipped - values)
        count = int(np.count_nonzero(moved))
        if count:
            self.count += count
            self.largest = max(self.largest, float(moved.max()))
        return clipped

    def checked(self, values: np.ndarray, upper: float, name: str, describe: Callable[[int], str]) -> np.ndarray:
        """`values` (of the field `name`) projected onto [0, upper] when within round-off of it; a NaN, or a
        value beyond ROUNDOFF (relative to max(upper, 1)), fails the step with the cell `describe(index)`."""
        bad = ~np.isfinite(values)
        if bad.any():
            raise StepFailure(f"{name} is not finite", describe(int(np.argmax(bad))))
        tolerance = ROUNDOFF * max(upper, 1.0)
        outside = (values < -tolerance) | (values > upper + tolerance)
        if outside.any():
            where = int(np.argmax(outside))
            raise StepFailure(f"{name} = {values[where]:.6g} outside [0, {upper:.6g}]", describe(where))
        return self.onto(values, 0.0, upper)
