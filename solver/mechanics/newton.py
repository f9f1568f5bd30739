"""Newton's method for the discrete equilibrium R(u) = 0 (paper Table 1, step 8), safeguarded.

* Euler predictor, Newton corrector: the first step uses the tangent of the
  last equilibrium (given as `predictor`: at the very first solve the
  stress-free, linear-elastic tangent), the next ones the exact consistent
  tangent at the iterate (`assembly`), which converges quadratically.  The
  tangent at the grown but undeformed start carries a compressive prestress
  |p| ~ 3 kappa alpha that exceeds mu from alpha ~ 0.007 on: it is indefinite
  and its Newton step inverts void elements at alpha = 0.1 (measured), while
  the predictor step there lands within 22 % of the residual.
* Inexact linear solves: with q the expected relative size of the coming
  step (the last one times the observed contraction), the linear solve's
  relative error is eta = 0.1 max(q, tol / q), within [1e-8, 1e-4] (1e-2 for
  the first step): below
  the Newton error while that matters, so the quadratic rate is kept, and
  no smaller than the final tolerance needs.  (The error, not the residual:
  see `linear.gmres`.)
* Backtracking: a step is halved (up to 8 times) while it would invert an
  element (det F <= 0 at a Gauss point or corner) or lower neither |R| nor
  the energy (Armijo: Pi(u + t du) <= Pi(u) + 1e-4 t R.du, when du is a
  descent direction; only while |R| > 1e-6 |R_ref|).  The energy is the
  better merit far from equilibrium (large growth), the residual near it,
  where the energy is flat to round-off.
* Converged when |R| <= tol |R_ref| AND the next increment predicted from
  the observed contraction, |du_k| * |du_k| / |du_k-1|, is <= tol |u|: the
  increment test without paying one more solve just to measure it.
  Increments are measured in the energy norm |v|_K = sqrt(v.K v) of the
  tangent K they were solved with (the Newton decrement).  The max norm
  would be ruled by the void: with stiffness 1e-4 of the biofilm's, its
  displacements are 1e4 times less determined by the forces, and a
  multigrid-preconditioned solve that is accurate to 1e-2 in energy can be
  off by 60 % there (docs/mechanics.md).
  |R_ref| is the growth load: the internal forces at u = 0, reactions included.

Failures are returned, not raised: the caller may cut the load step back.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .assembly import Evaluation
from .linear import LinearSolveError


@dataclass
class NewtonOutcome:
    u: np.ndarray
    evaluation: Evaluation
    converged: bool
    iterations: int = 0
    history: list[float] = field(default_factory=list)
    reason: str = ""


def energy_norm(matrix, v: np.ndarray) -> float:
    """sqrt|v.K v|: the increment measure (|v K v| in case K is indefinite far from equilibrium)."""
    return float(np.sqrt(abs(v @ (matrix @ v))))


def newton(evaluate: Callable[[np.ndarray, bool], Evaluation],
           solve: Callable[[object, np.ndarray, float], np.ndarray],
           u: np.ndarray, reference: float, tolerance: float, max_iterations: int,
           predictor=None, max_halvings: int = 8) -> NewtonOutcome:
    """Iterate from u; evaluate(u, tangent) -> Evaluation, solve(K, rhs, rtol) -> du."""
    ev = evaluate(u, True)
    if np.min(ev.min_det) <= 0:
        return NewtonOutcome(u, ev, False, reason="det F <= 0 at the starting point")
    r = float(np.linalg.norm(ev.residual))
    history = [r]
    if r <= tolerance * reference:
        return NewtonOutcome(u, ev, True, 0, history)
    previous_step = None
    for k in range(1, max_iterations + 1):
        if previous_step:  # q: the next step's relative size if the observed contraction holds
            q = max(relative * min(contraction, 1.0), 1e-300)
            eta = min(1e-4, max(1e-8, 0.1 * q, 0.1 * tolerance / q))
        else:
            eta = 1e-2
        try:
            matrix = predictor if k == 1 and predictor is not None else ev.matrix
            du = solve(matrix, -ev.residual, eta)
        except LinearSolveError as error:
            return NewtonOutcome(u, ev, False, k - 1, history, f"linear solver: {error}")
        step = 1.0
        for _ in range(max_halvings + 1):
            trial = u + step * du
            ev_trial = evaluate(trial, True)
            r_trial = float(np.linalg.norm(ev_trial.residual))
            slope = float(ev.residual @ du)
            # energy descent counts only far from equilibrium (near it the residual is the
            # sharper merit) and where the decrease is above the energy's round-off
            descent = (r > 1e-6 * reference and -slope > 1e-10 * abs(ev.energy)
                       and ev_trial.energy <= ev.energy + 1e-4 * step * slope)
            if np.min(ev_trial.min_det) > 0 and (r_trial < r or descent):
                break
            step *= 0.5
        else:
            reason = ("every step length down to 2^-%d inverts an element" % max_halvings
                      if np.min(ev_trial.min_det) <= 0 else "no step length lowers the residual or the energy")
            return NewtonOutcome(u, ev_trial, False, k, history, reason)
        size = step * energy_norm(matrix, du)
        contraction = size / previous_step if previous_step else r_trial / r
        u, ev, r, previous_step = trial, ev_trial, r_trial, size
        relative = size / max(energy_norm(matrix, u), 1e-300)
        history.append(r)
        if r <= tolerance * reference and relative * min(contraction, 1.0) <= tolerance:
            return NewtonOutcome(u, ev, True, k, history)
    return NewtonOutcome(u, ev, False, max_iterations, history,
                         f"not converged in {max_iterations} iterations (|R|/|R_ref| = {r / reference:.2e})")
