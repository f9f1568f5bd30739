"""Profile likelihoods (Raue et al. 2009, Bioinformatics 25:1923): an interval that need not be symmetric, and
whether the data determine a parameter at all.

The profile of parameter j is chi²_PL(u_j) = min over the other parameters of chi²(u) with u_j held: each point
re-optimises the others (`least_squares.fit` with u_j fixed), starting from the previous point. From the optimum
each branch steps outward (one branch per direction, each a fit of its own in the rounds of `rounds.run`),
adapting its step so that chi² rises by one to two per point (the others start where the last two points
extrapolate to, along the valley of correlated parameters), until chi²_PL exceeds the lowest chi² it has seen by
`THRESHOLD` (3.84: the 95 % point of chi² with one degree of freedom, a pointwise interval) or the branch reaches
the bound; a point more than `OVERSHOOT` past the threshold is followed by one half as far from the last point
below it, so that the crossing is bracketed closely. The interval's end is where the profile crosses the
threshold, interpolated linearly between the two points around it. A branch that reaches its bound still below
the threshold leaves the interval open there: the data do not determine the parameter on that side (practical
non-identifiability; flat everywhere: structural). With σ estimated, chi² is F, -2 log L with σ profiled out
(`likelihood`): every point re-estimates σ too."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .least_squares import Fit, Problem, fit
from .likelihood import THRESHOLD, Likelihood
from .rounds import Asking

MAX_POINTS = 12  # per branch
FIRST, SMALLEST, LARGEST = 0.05, 0.005, 0.25  # steps along the profiled coordinate (unit cube)
INNER_TOLERANCE = 0.1  # chi²: the re-optimisations need less than the optimum
OVERSHOOT = 2.0  # a point this far past the threshold is followed by one half as far from the last below it


@dataclass
class Branch:
    """One direction of one profile: the points (unit-cube value of the profiled coordinate, chi², whole point)."""

    parameter: int
    direction: int  # +1 toward the upper bound, -1 toward the lower
    points: list[tuple[float, float, np.ndarray]] = field(default_factory=list)
    evaluations: int = 0


def branch(best: Fit, j: int, direction: int, noise: np.ndarray, standard_error: float,
           likelihood: Likelihood = Likelihood()) -> Asking[Branch]:
    """Step the profile of coordinate j from the optimum `best` toward one bound (see the module); a generator
    (`rounds`)."""
    out = Branch(j, direction)
    problem = Problem(len(best.residuals), noise, best.steps, likelihood)
    # one standard error first (chi² + 1 where the profile is quadratic), then about twice that (+ 4: past 3.84)
    step = FIRST if not math.isfinite(standard_error) else float(np.clip(standard_error, SMALLEST, 2 * FIRST))
    here, previous, floor = best.x.copy(), best.chi2, best.chi2
    before = None  # the point before `here`
    for _ in range(MAX_POINTS):
        target = here[j] + direction * step
        at_bound = not 0.0 < target < 1.0
        target = float(np.clip(target, 0.0, 1.0))
        start = here.copy()
        if before is not None and here[j] != before[j]:  # the valley's direction, from the last two points
            start += (here - before) * (target - here[j]) / (here[j] - before[j])
        start = np.clip(start, 0.0, 1.0)
        start[j] = target
        found = yield from fit(start, problem, {j: target}, INNER_TOLERANCE, final_jacobian=False)
        out.points.append((target, found.chi2, found.x))
        out.evaluations += found.evaluations
        floor = min(floor, found.chi2)  # a profile may find lower chi² than the fit did
        rise = found.chi2 - floor
        if rise > THRESHOLD + OVERSHOOT and step > 2 * SMALLEST:
            step /= 2  # far past the threshold: a point between brackets the crossing more closely
            continue
        if rise > THRESHOLD:
            break
        if at_bound:
            break
        increment = found.chi2 - previous
        step = step / 2 if increment > 2.5 else step * 2 if increment < 0.8 else step
        step = float(np.clip(step, SMALLEST, LARGEST))
        before, here, previous = here, found.x.copy(), found.chi2
    return out


@dataclass(frozen=True)
class Profile:
    """A parameter's profile (both branches joined, increasing u) and its 95 % interval in the unit cube."""

    u: np.ndarray
    chi2: np.ndarray
    lower: float
    upper: float
    open_below: bool  # the interval reaches the lower bound (no crossing there)
    open_above: bool

    @property
    def identifiable(self) -> bool:
        return not (self.open_below or self.open_above)


def _crossing(points: list[tuple[float, float]], minimum: float) -> float | None:
    """Where the profile (points from the optimum outward) first exceeds minimum + THRESHOLD, interpolated."""
    for (u0, c0), (u1, c1) in zip(points, points[1:]):
        if c1 - minimum > THRESHOLD >= c0 - minimum:
            return u0 + (minimum + THRESHOLD - c0) / (c1 - c0) * (u1 - u0)
    return None


def profile(best: Fit, below: Branch, above: Branch, minimum: float) -> Profile:
    """Join the branches of one parameter and find its interval against the lowest chi² found (`minimum`: the
    optimum's, or lower if a profile found a lower one)."""
    j = below.parameter
    centre = (float(best.x[j]), best.chi2)
    sides = {}
    for side in (below, above):
        points = [centre] + sorted(((u, c) for u, c, _ in side.points), key=lambda p: abs(p[0] - centre[0]))
        crossing = _crossing(points, minimum)
        bound = 0.0 if side.direction < 0 else 1.0
        sides[side.direction] = (crossing if crossing is not None else bound, crossing is None)
    joined = sorted([centre] + [(u, c) for side in (below, above) for u, c, _ in side.points])
    u = np.array([p[0] for p in joined])
    return Profile(u, np.array([p[1] for p in joined]), sides[-1][0], sides[1][0], sides[-1][1], sides[1][1])
