"""Newton's method for the discrete equilibrium R(u) = 0 (paper Table 1, step 8), safeguarded and capped.

* Operator.  The first step uses the `operator` the caller gives (load
  stepping: the tangent with the start's stress, positive definite at a
  stable equilibrium) or the tangent at the start.  It is kept (a chord
  step: a residual costs a fraction of a tangent) while each step cuts |R|
  at least `1 / Settings.retangent`-fold: between the snapshots of a run the
  strains change little and the tangent hardly at all.  After a slower or damped step
  the tangent is reassembled at the iterate: exact Newton, quadratic where
  the problem is nonlinear (large growth).  A step from another operator
  that finds no descent is retried once with the tangent at the iterate.
* Inexact linear solves (forcing term, Eisenstat & Walker's choice 2):
  the relative residual asked of a linear solve is the square of the last
  observed contraction |R_k| / |R_k-1| (`forcing_first` for the first step),
  clipped to [forcing_min, forcing_max], and no smaller than what brings |R|
  to `forcing_safety` times the final tolerance.
* Backtracking: a step is halved (up to `max_halvings` times) while it would
  invert an element (det F <= 0 at a Gauss point or corner) or lower neither
  |R| nor the energy (Armijo, when du is a descent direction; only while
  |R| > 1e-6 |R_ref|: near equilibrium the energy is flat to round-off and
  the residual is the sharper merit).
* Converged when |R| <= tol |R_ref| AND the next increment predicted from
  the observed contraction, |du_k| min(1, |du_k| / |du_k-1|), is <= tol |u|.
  Increments are measured in the energy norm |v|_K = sqrt(v.K v) of the
  operator they were solved with: the max norm would be ruled by the void,
  whose displacements are 1e4 times less determined by the forces.
  |R_ref| is the growth load: the internal forces at u = 0, reactions included.

At most `max_iterations` steps, each with one linear solve and at most
`max_halvings + 1` residuals.  Failures are returned, not raised: the
caller may cut the load step back.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .assembly import Evaluation
from .linear import BudgetSpent, LinearSolveError
from .settings import Settings


@dataclass
class NewtonOutcome:
    u: np.ndarray
    evaluation: Evaluation
    converged: bool
    iterations: int = 0
    history: list[float] = field(default_factory=list)
    reason: str = ""
    spent: bool = False  # stopped because the snapshot's linear-solver budget is spent


TABLE_2_NU = 0.49  # the paper's Poisson ratio: kappa = 49.7 mu


def nearly_incompressible(nu: float, kappa: float, mu: float, growth: float) -> str:
    """What a refused solve adds when its material is nearer incompressible than Table 2's (nu > 0.49): the
    growth increment `growth` (largest change of alpha in the solve) is a volumetric prestress 3 kappa growth,
    which beside mu makes the tangent indefinite and ill-conditioned at once (loading.py), beyond what the Krylov
    solves get past; '' otherwise."""
    if nu <= TABLE_2_NU:
        return ""
    table_2 = 2 * (1 + TABLE_2_NU) / (3 * (1 - 2 * TABLE_2_NU))
    return (f"; the nearly incompressible limit under growth is the cause: nu = {nu:g} makes the bulk modulus kappa "
            f"= {kappa / mu:.3g} mu (Table 2's nu = {TABLE_2_NU:g}: {table_2:.3g} mu), and growing alpha by up to "
            f"{growth:.3g} in this solve is a volumetric prestress 3 kappa d(alpha) = "
            f"{3 * kappa * growth / mu:.3g} mu: use params.nu <= {TABLE_2_NU:g}, or grow less per solve (more outputs, "
            f"mechanics.every = 1; docs/mechanics.md, \"Nearly incompressible growth\")")


def energy_norm(matrix, v: np.ndarray) -> float:
    """sqrt|v.K v|: the increment measure (|v K v| in case K is indefinite far from equilibrium)."""
    return float(np.sqrt(abs(v @ (matrix @ v))))


def forcing(r: float, contraction: float | None, target: float, s: Settings) -> float:
    """Relative residual asked of the next linear solve (see the module docstring)."""
    expected = s.forcing_first if contraction is None else contraction**2
    return float(np.clip(max(expected, s.forcing_safety * target / r), s.forcing_min, s.forcing_max))


def newton(evaluate: Callable[[np.ndarray, bool], Evaluation], linear, u: np.ndarray, reference: float,
           tolerance: float, max_iterations: int, settings: Settings, operator=None) -> NewtonOutcome:
    """Iterate from u; evaluate(u, tangent) -> Evaluation, linear.solve(K, rhs, rtol) -> du (and
    linear.detach() before a newer tangent is assembled)."""
    s = settings
    ev = evaluate(u, operator is None)
    if np.min(ev.min_det) <= 0:
        return NewtonOutcome(u, ev, False, reason="det F <= 0 at the starting point")
    r = float(np.linalg.norm(ev.residual))
    history = [r]
    if r <= tolerance * reference:
        return NewtonOutcome(u, ev, True, 0, history)
    matrix = operator if operator is not None else ev.matrix
    exact, operator = operator is None, None  # matrix is the tangent at u; held once
    previous_size = contraction = None
    for k in range(1, max_iterations + 1):
        eta = forcing(r, contraction, tolerance * reference, s)
        try:
            du = linear.solve(matrix, -ev.residual, eta)
        except LinearSolveError as error:
            return NewtonOutcome(u, ev, False, k - 1, history, f"linear solver: {error}",
                                 isinstance(error, BudgetSpent))
        step, slope = 1.0, float(ev.residual @ du)
        for _ in range(s.max_halvings + 1):
            trial = u + step * du
            ev_trial = evaluate(trial, False)
            r_trial = float(np.linalg.norm(ev_trial.residual))
            # energy descent counts only far from equilibrium and above the energy's round-off
            descent = (r > 1e-6 * reference and -slope > 1e-10 * abs(ev.energy)
                       and ev_trial.energy <= ev.energy + s.armijo * step * slope)
            if np.min(ev_trial.min_det) > 0 and (r_trial < r or descent):
                break
            step *= 0.5
        else:
            if not exact:  # an operator from elsewhere misled the step: the tangent at u, then again
                linear.detach()
                matrix = ev.matrix = None  # no tangent held while the next is assembled
                ev, exact, contraction = evaluate(u, True), True, None
                matrix = ev.matrix
                continue
            reason = (f"every step length down to 2^-{s.max_halvings} inverts an element"
                      if np.min(ev_trial.min_det) <= 0 else "no step length lowers the residual or the energy")
            return NewtonOutcome(u, ev_trial, False, k, history, reason)
        size = step * energy_norm(matrix, du)
        contraction = r_trial / r
        shrink = size / previous_size if previous_size else contraction
        u, ev, r, previous_size = trial, ev_trial, r_trial, size
        history.append(r)
        relative = size / max(energy_norm(matrix, u), 1e-300)
        if r <= tolerance * reference and relative * min(shrink, 1.0) <= tolerance:
            return NewtonOutcome(u, ev, True, k, history)
        exact = False
        if contraction > s.retangent or step < 1.0:  # slow or damped: the tangent at the iterate
            linear.detach()
            matrix = ev.matrix = None  # no tangent held while the next is assembled
            ev, exact = evaluate(u, True), True  # (the residual again: cheaper than a tangent per trial)
            matrix = ev.matrix
    return NewtonOutcome(u, ev, False, max_iterations, history,
                         f"not converged in {max_iterations} iterations (|R|/|R_ref| = {r / reference:.2e})")
