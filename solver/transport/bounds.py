"""Fields kept within their bounds: round-off projected onto a bound, anything beyond it a failed step.

A linear solve returns c or phi to within its tolerance, so a value can lie a
little outside a bound that the exact discrete solution keeps (0 <= c <= the
largest held value; 0 <= phi <= max(phi^n + dt k_alpha alpha^n)).  Within
`ROUNDOFF` of a bound it is projected onto the bound; beyond, the step fails
(`StepFailure`) and the clock bisects it.

What the model lets phi and alpha reach (`Expansion`, docs/model.md "Bounds") comes from the parameters and
the initial fields, not from the run's own values: advection and diffusion never raise max phi (maximum
principle), so its largest value P(t) and alpha's A(t) grow at most as P' = k_alpha A, A' = k_alpha P (Eqs.
34, 36), i.e. P(t) = P0 cosh(k_alpha t) + A0 sinh(k_alpha t).  The scheme's steps obey the same recursion
discretely (phi^{n+1} <= P^n + dt k_alpha A^n, then alpha^{n+1} <= A^n + dt k_alpha P^{n+1}): every step checks
both fields against it.  When the fields outgrow `CEILING`, the round-off a check allows (ROUNDOFF times the
bound) exceeds the density's own scale, 1: biofilm (phi >= 1/2) can no longer be told from void, and the run
stops (`Runaway`) instead of computing numbers that mean nothing.

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
CEILING = 1.0 / ROUNDOFF  # beyond it a check's round-off exceeds phi's own scale (module docstring)


@dataclass(frozen=True)
class Expansion:
    """The largest phi and alpha the model allows after the steps taken so far (module docstring)."""

    phi: float
    alpha: float

    @classmethod
    def initially(cls, phi: np.ndarray, alpha: np.ndarray) -> Expansion:
        return cls(float(np.max(phi, initial=0.0)), max(float(np.max(alpha, initial=0.0)), 0.0))

    def after(self, dt: float, k_alpha: float) -> Expansion:
        """The bounds one step of dt later, as the scheme steps (phi with alpha^n, then alpha with phi^{n+1})."""
        phi = self.phi + dt * k_alpha * self.alpha
        return Expansion(phi, self.alpha + dt * k_alpha * phi)

    def within(self, phi: np.ndarray, alpha: np.ndarray, describe: Callable[[int], str]) -> None:
        """StepFailure naming the cell if phi or alpha exceeds its bound by more than round-off."""
        for name, values, upper in (("biofilm phi", phi, self.phi), ("expansion alpha", alpha, self.alpha)):
            where = int(np.argmax(values))
            if values[where] > upper * (1 + ROUNDOFF) + ROUNDOFF:
                raise StepFailure(f"{name} = {values[where]:.6g} beyond {upper:.6g}, what the model allows it to "
                                  "reach by now (docs/model.md, Bounds)", describe(where))


def model_bound(phi0: float, alpha0: float, k_alpha: float, t: float) -> tuple[float, float]:
    """(phi, alpha) the model allows after a time t from largest values phi0, alpha0: P0 cosh + A0 sinh, A0 cosh +
    P0 sinh of k_alpha t (inf when beyond double precision)."""
    with np.errstate(over="ignore"):
        cosh, sinh = np.cosh(k_alpha * t), np.sinh(k_alpha * t)

    def times(a: float, b: float) -> float:
        return a * b if a else 0.0  # 0 * inf is no growth, not NaN

    return times(phi0, cosh) + times(alpha0, sinh), times(alpha0, cosh) + times(phi0, sinh)


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
