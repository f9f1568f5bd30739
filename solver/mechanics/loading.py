"""Load stepping: from the last equilibrium to the requested (phi, alpha), in as few Newton solves as work.

Each snapshot is a homotopy from the last converged state (phi0, alpha0, u0)
to the requested (phi1, alpha1): at s in (0, 1] both fields are interpolated
linearly and Newton starts from the previous step's u.  The full step s = 1
is tried first; when Newton fails (an element would invert, no descent, no
convergence, no linear solve) the step is halved, and after a success it
doubles again.

Each load step's first operator is the tangent with the target's phi (its
stiffness) but the start's alpha, at the start's u: the tangent of the last
equilibrium, updated for where the biofilm moved.  It is positive definite
when that equilibrium was stable, unlike the tangent at the target's alpha,
which adds the prestress of the whole growth increment, ~3 kappa d(alpha),
and is indefinite once that exceeds mu (newton.py).  From rest it is the
stress-free, linear-elastic tangent.  (Even between the snapshots of a run,
where that prestress is small, the tangent at the target's alpha was the
worse operator: its Newton steps stopped descending, docs/mechanics.md.)

Bounded: at most `Settings.max_load_steps` Newton solves and
`Settings.max_total_newton` Newton steps per snapshot, no step below
`Settings.smallest_load_step`, and none once the linear solver's budget
(Krylov iterations, preconditioner builds) is spent; then `Refused`,
carrying the last outcome and the record of what was tried.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .newton import NewtonOutcome, newton
from .settings import Settings


@dataclass
class Attempts:
    """What a snapshot's solve tried, for its report (and its failure message)."""

    steps: list[tuple[float, float, bool, int]] = field(default_factory=list)  # (from, to, converged, Newton)
    history: list[float] = field(default_factory=list)  # |R| after every Newton step, all load steps

    @property
    def newton(self) -> int:
        return sum(step[3] for step in self.steps)

    @property
    def converged(self) -> int:
        return sum(step[2] for step in self.steps)

    def summary(self) -> str:
        smallest = min((b - a for a, b, *_ in self.steps), default=1.0)
        return (f"{len(self.steps)} load steps ({self.converged} converged, smallest {smallest:.3g} of the way), "
                f"{self.newton} Newton steps")


class Refused(Exception):
    """Load stepping gave up: the last Newton outcome, the fraction of the way reached, and why."""

    def __init__(self, outcome: NewtonOutcome, reached: float, target: float, why: str):
        self.outcome, self.reached, self.target, self.why = outcome, reached, target, why
        super().__init__(why)


def step_load(system: Callable[[float, float], Callable], linear, u: np.ndarray, reference: float,
              tolerance: float, max_newton: int, settings: Settings, attempts: Attempts) -> NewtonOutcome:
    """Follow s from 0 to 1.  system(s_phi, s_alpha) -> evaluate(u, tangent) at phi(s_phi), alpha(s_alpha)."""
    s_done, ds, outcome = 0.0, 1.0, None
    while s_done < 1.0:
        target = min(1.0, s_done + ds)
        left = settings.max_total_newton - attempts.newton
        if len(attempts.steps) >= settings.max_load_steps or left <= 0:
            why = (f"all {settings.max_load_steps} load steps" if left > 0
                   else f"all {settings.max_total_newton} Newton steps") + " spent"
            raise Refused(outcome, s_done, target, why)
        if outcome is not None:  # no tangent held while the next is assembled
            linear.detach()
            outcome.evaluation.matrix = None
        # the first operator: the start's stress, the target's stiffness (passed on, not held here)
        outcome = newton(system(target, target), linear, u, reference, tolerance, min(max_newton, left),
                         settings, operator=system(target, s_done)(u, True).matrix)
        attempts.steps.append((s_done, target, outcome.converged, outcome.iterations))
        attempts.history.extend(outcome.history)
        if outcome.converged:
            u, s_done = outcome.u, target
            ds = min(2.0 * ds, 1.0)
            continue
        if outcome.spent:
            raise Refused(outcome, s_done, target, "the linear solver's budget is spent")
        ds /= 2.0
        if ds < settings.smallest_load_step * (1 - 1e-12):
            raise Refused(outcome, s_done, target, f"no load step down to {settings.smallest_load_step:.3g} "
                                                   "of the way converged")
    return outcome
