"""Weighted least squares in the unit cube of the bounds, with finite-difference Jacobians asked for in rounds.

The parameters are mapped onto [0, 1] each (log10 for log bounds: `plans.designs.Range`), so one step size and one
tolerance fit every parameter. The residuals are r_i = (model_i - measurement_i) / sigma_i; chi² = sum r_i². `fit`
minimises it by Levenberg-Marquardt (damping relative to the diagonal of J^T J, a coordinate at a bound that the
gradient pushes against held there, steps cut back into the cube), and ends when the undamped Gauss-Newton step
would lower chi² by less than `TOLERANCE` (absolute: what matters beside the 3.84 of a 95 % interval; judged on the
damped step, a few rejected steps would end it anywhere). scipy's bounded `trf` ended on the size of its steps,
which the model's small jumps shrink: on the tiny agar twin it stopped at chi² 19 where 3.5 was to be had. With σ
estimated (`likelihood`) chi² is -2 log L with σ profiled out (F): the steps come from the weighted least squares
that has F's gradient and Gauss-Newton Hessian, and are accepted, and convergence judged, on F (without: chi², the
same numbers). The Jacobian is forward differences (backward at an upper bound), their k runs asked for at once,
and offered with the point itself (`rounds.Ask.soon`: k + 1 runs in one round, taken only when workers would
otherwise wait; the path is the same either way).  `fit` is a generator: it yields what it needs (`rounds`).

The step is chosen against the observables' own resolution (`noise`: per measurement the smallest change
of the model that is not noise, in residual units): a column whose largest change is less than `SIGNAL`
times the noise is computed again with a larger step, up to `MAX_STEP`; one that moves by more than ten
times that takes a smaller step next time, down to `STEP`.  Sub-cell observables change
smoothly with the parameters except for small jumps when a discrete event of the solver moves (a cell
entering the front band): measured relative jumps up to 1e-4 (biomass) and 1e-3 (max_thickness) for
relative parameter changes of 1e-4 to 1e-3 (docs/calibration.md), hence `STEP`, 1 % of the range.

A failed simulation is a penalty, not a crash: its residuals are `PENALTY` each (the trust region shrinks
away from it); a failed neighbour of a Jacobian leaves that column zero for that step.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .likelihood import PENALTY, Likelihood
from .objective import key
from .rounds import Ask, Asking

STEP = 0.01  # the smallest finite-difference step, in units of the range (unit cube)
MAX_STEP = 0.05
SIGNAL = 10.0  # a Jacobian column must move some residual by this many times its noise (else a larger step)
TOLERANCE = 0.01  # converged when a step would lower chi² by less (a 95 % interval is chi²_min + 3.84)
DAMPING = 1e-3  # the first Levenberg-Marquardt damping, relative to the diagonal of J^T J
MAX_ITERATIONS = 25


@dataclass
class Fit:
    """Where one minimisation ended: the point (unit cube), chi² (F: -2 log L with σ profiled out, when σ is
    estimated: `likelihood`), the residuals and the Jacobian there (free columns; the fixed ones zero) in units
    of σ (σ̂ where it is estimated), the steps used, what it cost and why it ended."""

    x: np.ndarray
    chi2: float
    residuals: np.ndarray
    jacobian: np.ndarray
    steps: np.ndarray
    evaluations: int = 0
    message: str = ""
    failed: int = 0  # evaluations that were failed simulations (penalties)
    stopped: bool = False  # ended early: it joined another start
    path: list = field(default_factory=list)  # (point, chi²) of every evaluated point, in order
    sigma: np.ndarray = field(default_factory=lambda: np.zeros(0))  # σ̂ per estimated group (measurement units)


class Problem:
    """The residuals of one fit, remembered per point (`objective.key`), with finite-difference Jacobians; its
    methods are generators that yield an `Ask` when they need residuals not yet known (`rounds`)."""

    def __init__(self, n: int, noise: np.ndarray, steps: np.ndarray, likelihood: Likelihood = Likelihood()):
        self.n, self.noise, self.likelihood = n, np.asarray(noise, float), likelihood
        self.steps = np.array(steps, dtype=float)
        self.known: dict[tuple, np.ndarray] = {}
        self.failed = 0
        self.path: list = []

    def _store(self, points, results) -> None:
        for point, result in zip(points, results):
            if key(point) in self.known:
                continue
            if result is None:
                self.failed += 1
                result = np.full(self.n, PENALTY)
            self.known[key(point)] = np.asarray(result, dtype=float)
            self.path.append((np.array(point), self.value(self.known[key(point)])))

    def value(self, residuals: np.ndarray) -> float:
        """chi², or F with σ estimated (`likelihood`)."""
        return self.likelihood.value(residuals)

    def ended(self, x: np.ndarray, residuals: np.ndarray, jacobian: np.ndarray, evaluations: int, message: str,
              stopped: bool = False) -> Fit:
        """A `Fit` at `x` (residuals and Jacobian as evaluated: it weights them by the σ̂ there)."""
        return Fit(x, self.value(residuals), *self.likelihood.weighted(residuals, jacobian), self.steps.copy(),
                   evaluations, message, self.failed, stopped, self.path, self.likelihood.sigmas(residuals))

    def residuals(self, points: list[np.ndarray], soon: tuple[np.ndarray, ...] = ()) -> Asking[list[np.ndarray]]:
        """The residuals at `points`, asked for if not known (with `soon`, which the round may take too)."""
        wanted = [p for p in points if key(p) not in self.known]
        if wanted:
            later = [p for p in soon if key(p) not in self.known]
            self._store(wanted + later, (yield Ask(wanted, later)))
        return [self.known[key(p)] for p in points]

    def neighbour(self, point: np.ndarray, j: int) -> np.ndarray:
        step = self.steps[j] if point[j] + self.steps[j] <= 1.0 else -self.steps[j]
        moved = point.copy()
        moved[j] += step
        return moved

    def at(self, point: np.ndarray, free: list[int]) -> Asking[np.ndarray]:
        """The residuals at `point`; its Jacobian's neighbours asked for with it if the round has room."""
        found = yield from self.residuals([point], tuple(self.neighbour(point, j) for j in free))
        return found[0]

    def jacobian(self, point: np.ndarray, free: list[int]) -> Asking[np.ndarray]:
        """d r / d u at `point` over the free coordinates (the others zero), each step large enough against the
        noise (`SIGNAL`)."""
        centre = (yield from self.residuals([point]))[0]
        columns = np.zeros((self.n, len(point)))
        todo = list(free)
        while todo:
            moved = {j: self.neighbour(point, j) for j in todo}
            values = dict(zip(todo, (yield from self.residuals(list(moved.values())))))
            again = []
            for j in todo:
                delta = values[j] - centre
                h = moved[j][j] - point[j]
                if np.all(values[j] == PENALTY) or np.all(centre == PENALTY):
                    columns[:, j] = 0.0
                    continue
                columns[:, j] = delta / h
                signal = float(np.max(np.abs(delta) / self.noise))
                if signal < SIGNAL and self.steps[j] < MAX_STEP:
                    self.steps[j] = min(MAX_STEP, self.steps[j] * max(2.0, 1.2 * SIGNAL / max(signal, 1e-12)))
                    again.append(j)
                elif signal > 10 * SIGNAL:
                    self.steps[j] = max(STEP, self.steps[j] / 2)
            todo = again
        return columns


def fit(start: np.ndarray, problem: Problem, fixed: dict[int, float] | None = None, tolerance: float = TOLERANCE,
        max_iterations: int = MAX_ITERATIONS, final_jacobian: bool = True) -> Asking[Fit]:
    """Minimise chi² (F with σ estimated) from `start` inside the unit cube, the coordinates in `fixed` held at
    their values: Levenberg-Marquardt (module docstring); `final_jacobian`: the Jacobian at the end too (for the
    covariance; a profile's points need none).  A generator (`rounds`): it yields the points it needs."""
    fixed = fixed or {}
    k = len(start)
    free = [j for j in range(k) if j not in fixed]
    x = np.clip(np.array(start, dtype=float), 0.0, 1.0)
    for j, value in fixed.items():
        x[j] = value
    r = yield from problem.at(x, free)
    if not free:
        return problem.ended(x, r, np.zeros((problem.n, k)), 1, "nothing free")
    jacobian = yield from problem.jacobian(x, free)
    damping, evaluations, message = DAMPING, 1, f"stopped after {max_iterations} iterations"
    for _ in range(max_iterations):
        # converged when even the undamped Gauss-Newton step would gain less than the tolerance: judged on the
        # full step, not on a damped one (which a few rejected steps make small wherever it is)
        current = problem.value(r)
        weighted = problem.likelihood.weighted(r, jacobian)
        full = _step(x, *weighted, free, 0.0)
        if current - problem.value(r + jacobian @ full) < tolerance:
            message = f"converged: a Gauss-Newton step would lower chi² by less than {tolerance:g}"
            break
        step = _step(x, *weighted, free, damping)
        predicted = current - problem.value(r + jacobian @ step)
        trial = x + step
        r_trial = yield from problem.at(trial, free)
        evaluations += 1
        if current - problem.value(r_trial) > 0.25 * predicted:
            x, r = trial, r_trial
            jacobian = yield from problem.jacobian(x, free)
            damping = max(damping / 4, 1e-9)
        else:
            damping *= 4
            if damping > 1e8:
                message = "stalled: no step lowers chi² (a plateau, or noise)"
                break
    if final_jacobian:
        jacobian = yield from problem.jacobian(x, free)
    return problem.ended(x, r, jacobian, evaluations, message)


def _step(x: np.ndarray, r: np.ndarray, jacobian: np.ndarray, free: list[int], damping: float) -> np.ndarray:
    """The damped Gauss-Newton step over the free coordinates that are not held at a bound they push against, cut
    back to stay inside the unit cube."""
    gradient = jacobian.T @ r
    moving = [j for j in free if not ((x[j] <= 0.0 and gradient[j] > 0) or (x[j] >= 1.0 and gradient[j] < 0))]
    step = np.zeros_like(x)
    if not moving:
        return step
    a = jacobian[:, moving].T @ jacobian[:, moving]
    scale = np.maximum(np.diag(a), 1e-12 * max(np.max(np.diag(a)), 1e-300))
    step[moving] = np.linalg.lstsq(a + max(damping, 1e-12) * np.diag(scale), -gradient[moving], rcond=None)[0]
    return np.clip(x + step, 0.0, 1.0) - x
