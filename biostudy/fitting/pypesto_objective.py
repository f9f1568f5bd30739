"""A calibration's objective as pyPESTO takes it, so that a lab can run its own pipeline on biostudy's simulations.

pyPESTO (Schälte et al. 2023, Bioinformatics 39:btad711) splits a fit into an objective, a problem (bounds, scales)
and a result; its optimisers and samplers call `pypesto.Objective` for residuals and their sensitivities. `problem`
wraps a calibration's `Objective` (the same simulations, case files and workers as ``biostudy calibrate``):
parameters on the fit's own scale (log10 of a log range's value, else the value itself), bounds the calibration's,
residuals (model - measurement) / σ, and their sensitivities by biostudy's own finite differences
(`least_squares.Problem.jacobian`: forward steps in the unit cube chosen against the observables' resolution, kept
from call to call), divided by each range's width on that scale; its function value 0.5 chi²
(`pypesto.util.res_to_fval`) and gradient J^T r for its samplers and gradient-based optimisers. A failed simulation
answers `PENALTY` residuals and zero sensitivities, as in biostudy's own fit. σ named in the table (estimated) has
no residual form pyPESTO's least squares take (its likelihood is -2 log L with σ profiled out): such a calibration
is refused. The simulations run on biostudy's side (its workers or Dask cluster, one batch per Jacobian); pyPESTO's
engine stays its default single-core one (a multi-process engine would pickle the workers).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import rounds
from .least_squares import STEP, Problem
from .objective import Objective


def _scale(low: float, high: float, log: bool) -> tuple[float, float]:
    return (float(np.log10(low)), float(np.log10(high))) if log else (float(low), float(high))


class Residuals:
    """res(x) and sres(x) of a calibration's objective on the fit's scale (module docstring); every point
    evaluated once (the objective remembers it), the finite-difference steps kept between calls."""

    def __init__(self, objective: Objective, bounds: list[tuple[float, float, bool]]):
        if objective.likelihood.groups:
            raise ValueError("the measurement table names σ to estimate (noiseParameters): pyPESTO's residuals "
                             "take σ as numbers; give them as numbers for pyPESTO")
        self.objective = objective
        ends = np.array([_scale(*b) for b in bounds])
        self.lower, self.upper = ends[:, 0], ends[:, 1]
        self.problem = Problem(objective.n, objective.noise, np.full(objective.k, STEP), objective.likelihood)

    def unit(self, x: np.ndarray) -> np.ndarray:
        """A point of the fit's scale in the unit cube of the bounds."""
        return np.clip((np.asarray(x, dtype=float) - self.lower) / (self.upper - self.lower), 0.0, 1.0)

    def _run(self, asking) -> Any:
        return rounds.run({"one": asking}, self.objective.evaluate, workers=self.objective.workers)["one"]

    def res(self, x: np.ndarray) -> np.ndarray:
        return self._run(self.problem.residuals([self.unit(x)]))[0]

    def sres(self, x: np.ndarray) -> np.ndarray:
        columns = self._run(self.problem.jacobian(self.unit(x), list(range(self.objective.k))))
        return columns / (self.upper - self.lower)

    def fun(self, x: np.ndarray) -> float:
        """pyPESTO's function value, 0.5 chi² (what its samplers and gradient-based optimisers take)."""
        return 0.5 * float(np.sum(self.res(x) ** 2))

    def grad(self, x: np.ndarray) -> np.ndarray:
        return self.sres(x).T @ self.res(x)

    def __deepcopy__(self, memo) -> Residuals:
        """Itself: pyPESTO copies objectives (its Problem, its multi-thread engine); a copy would run the same
        simulations and forget which it has."""
        return self


def problem(objective: Objective, bounds: list[tuple[float, float, bool]]):
    """A `pypesto.Problem` of a calibration's objective: `bounds` (low, high, log) per parameter in the
    objective's order; its `objective` gives res and sres (module docstring)."""
    import pypesto  # lazily: the optional extra pypesto

    found = Residuals(objective, bounds)
    scales = ["log10" if log else "lin" for _, _, log in bounds]
    wrapped = pypesto.Objective(fun=found.fun, grad=found.grad, res=found.res, sres=found.sres,
                                x_names=list(objective.names))
    return pypesto.Problem(wrapped, lb=found.lower, ub=found.upper, x_names=list(objective.names), x_scales=scales,
                           copy_objective=False)
