"""phi, c and alpha together: the state of the transport and one step of it.

A step of length dt (paper Eqs. 34-36; the laws as `problem.laws` says):
  1. the growth velocity from c^n (the nutrient is quasi-steady in phi^n);
  2. phi^{n+1} by implicit Euler with alpha^n as source;
  3. alpha^{n+1} from phi^{n+1} (Eq. 36) or from phi^n and phi^{n+1} (Table 1);
  4. c^{n+1} for phi^{n+1} (transient: and c^n, backward Euler over dt), which the
     next step starts from; CG starts from the
     parabola through the last three c's (their times need not be equidistant)
     extrapolated to t + dt: a smaller initial residual, fewer iterations, the
     same answer within the tolerance (measured: docs/transport.md).
Every stage checks for NaN and bounds and raises `StepFailure`; the clock
(`timeloop`) decides what to do about it.  Wall time per stage is kept in
`timings` so that a run can say where its time went.
"""
from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from ..counters import Counters
from ..parallel import SERIAL, Team
from ..parallel.blas import blas_threads
from ..problem import Parameters, Problem
from .biofilm import Biofilm
from .bounds import CEILING, Expansion, model_bound
from .courant import courant_rate
from .expansion import grow, table1
from .finite_volume import FiniteVolumeGrid
from .nutrient import Nutrient


@dataclass(frozen=True)
class State:
    """Transport fields on the active cells at time t.  For the next nutrient solve's starting guess only:
    `c_rate` is dc/dt over the step that led here (of length `c_span`), `c_curvature` the second divided
    difference of c over the last two steps (None at the start, or when c was not solved)."""

    t: float
    phi: np.ndarray
    alpha: np.ndarray
    c: np.ndarray | None
    c_rate: np.ndarray | None = None
    c_span: float = 0.0
    c_curvature: np.ndarray | None = None
    courant: float = 0.0  # the Courant number of the step that led here (courant.py)
    expansion: Expansion | None = None  # the largest phi and alpha the model allows by t (bounds.py)

    def c_guess(self, dt: float) -> np.ndarray | None:
        """c extrapolated to t + dt: Newton's parabola through the last three c's, or the line through the
        last two, or c itself."""
        if self.c is None or self.c_rate is None:
            return self.c
        if self.c_curvature is None:
            return self.c + dt * self.c_rate
        return self.c + dt * (self.c_rate + (dt + self.c_span) * self.c_curvature)

    def after(self, dt: float, phi: np.ndarray, alpha: np.ndarray, c: np.ndarray, courant: float = 0.0,
              expansion: Expansion | None = None) -> State:
        """The state dt later with these fields, its c's rate and curvature updated."""
        if self.c is None:
            return State(self.t + dt, phi, alpha, c, courant=courant, expansion=expansion)
        rate = (c - self.c) / dt
        curvature = None if self.c_rate is None else (rate - self.c_rate) / (dt + self.c_span)
        return State(self.t + dt, phi, alpha, c, rate, dt, curvature, courant, expansion)


class Transport:
    """Owns the cached operators of one problem and advances its state (on the threads of `team`)."""

    def __init__(self, problem: Problem, team: Team = SERIAL):
        self.problem = problem
        self.team = team
        self.fv = FiniteVolumeGrid(problem.grid, problem.obstacle)
        self.nutrient = Nutrient(self.fv, problem.params, problem.laws.consumption, problem.nutrient_held,
                                 problem.nutrient_value, problem.numerics.nutrient_tolerance, problem.nutrient_faces,
                                 team)
        self.transient = problem.laws.nutrient == "transient"
        if problem.c0 is None and not self.transient:  # the first solve's hierarchy before the biofilm's operators
            with blas_threads(1):  # exist (peak memory); its coarsest pseudo-inverse:
                self.nutrient.prepare(self.fv.to_active(problem.phi0))  # one BLAS thread
        self.biofilm = Biofilm(self.fv, problem.params, problem.numerics, self.nutrient.faces, team)
        self.fv.release_laplacian()  # the operators made from it hold what they need of it
        self.timings = defaultdict(float)
        self.largest_numerical_diffusion = 0.0
        self._velocity: tuple[State, list[np.ndarray], float] | None = None  # of the last state stepped from

    def initial(self) -> State:
        """The state at the problem's start: from rest (alpha = 0; c solved for phi0, or a transient nutrient
        held at its sources and 0 elsewhere) or, continuing a run, its last state as given."""
        problem = self.problem
        phi = self.fv.to_active(problem.phi0)
        alpha = np.zeros_like(phi) if problem.alpha0 is None else self.fv.to_active(problem.alpha0)
        if problem.c0 is not None:
            c = self.fv.to_active(problem.c0)
        else:
            c = self.nutrient.c_held.copy() if self.transient else self._nutrient(phi, None, None, 0.0)
        return State(problem.start_time, phi, alpha, c, expansion=self._bounded(phi, alpha))

    def _bounded(self, phi, alpha) -> Expansion | None:
        """The bounds of Eq. 36's growth from these fields (`bounds.Expansion`); None under Table 1's expansion,
        whose alpha follows phi's changes and has no bound from the parameters alone (`transport.expansion`)."""
        return Expansion.initially(phi, alpha) if self.problem.laws.expansion != "table1" else None

    def _nutrient(self, phi, guess, before, dt):
        start = time.perf_counter()
        c = self.nutrient.solve(phi, guess, before if self.transient else None, dt)
        self.timings["nutrient"] += time.perf_counter() - start
        return c

    def velocity(self, state: State) -> tuple[list[np.ndarray], float]:
        """The face velocities from `state` (c^n, and phi^n for the front velocity) and the Courant number of a
        unit step with them (1/T*; `courant.courant_rate`), kept for the step from that state."""
        if self._velocity is None or self._velocity[0] is not state:
            start = time.perf_counter()
            w = self.biofilm.velocity(state.c, state.phi)
            if not self.biofilm.tvd:  # upwind's own estimate; TVD's is smaller and has no such formula
                self.largest_numerical_diffusion = max(self.largest_numerical_diffusion,
                                                       self.biofilm.numerical_diffusion(w))
            self._velocity = (state, w, courant_rate(self.fv, w))
            self.timings["velocity"] += time.perf_counter() - start
        return self._velocity[1], self._velocity[2]

    def _expansion(self, alpha, phi_before, phi, dt):
        """alpha^{n+1}: Eq. 36, or Table 1's local equation (`transport.expansion`)."""
        k_alpha = self.problem.params.k_alpha
        if self.problem.laws.expansion == "table1":
            return table1(alpha, phi_before, phi, k_alpha, self.fv.describe)
        return grow(alpha, phi, k_alpha, dt)

    def step(self, state: State, dt: float, with_nutrient: bool = True) -> State:
        """State after dt; c at the end only if `with_nutrient` (step doubling skips it)."""
        clock = time.perf_counter
        w, rate = self.velocity(state)
        courant = dt * rate
        after_velocity = clock()
        phi = self.biofilm.step(state.phi, state.alpha, w, dt)
        after_biofilm = clock()
        alpha = self._expansion(state.alpha, state.phi, phi, dt)
        expansion = None
        if state.expansion is not None:  # (none under Table 1, nor in a bare State of a test of the clock)
            expansion = state.expansion.after(dt, self.problem.params.k_alpha)
            expansion.within(phi, alpha, self.fv.describe)
        self.timings["biofilm"] += after_biofilm - after_velocity
        self.timings["expansion"] += clock() - after_biofilm
        if not with_nutrient:
            return State(state.t + dt, phi, alpha, None, courant=courant, expansion=expansion)
        c = self._nutrient(phi, state.c_guess(dt), state.c, dt)
        return state.after(dt, phi, alpha, c, courant, expansion)

    def runaway(self, state: State) -> tuple[str, str] | None:
        """(cause, cell) when phi or alpha has outgrown what the solver resolves (`bounds.CEILING`), else None."""
        largest = max(float(np.max(state.phi, initial=0.0)), float(np.max(state.alpha, initial=0.0)))
        if largest <= CEILING:
            return None
        cell = int(np.argmax(np.maximum(state.phi, state.alpha)))
        problem = self.problem
        k_alpha = problem.params.k_alpha
        start = Expansion.initially(problem.phi0, np.zeros(1) if problem.alpha0 is None else problem.alpha0)
        allowed = model_bound(start.phi, start.alpha, k_alpha, problem.t_end - problem.start_time)[0]
        reach = f"{allowed:.3g}" if np.isfinite(allowed) else "beyond 1e308"
        return (f"the expansion feedback runs away: phi and alpha reach {state.phi[cell]:.3g} and "
                f"{state.alpha[cell]:.3g}, beyond {CEILING:.0e}, where round-off exceeds their own scale and biofilm "
                f"can no longer be told from void; Eqs. 34 and 36 let phi grow as cosh(k_alpha t), with k_alpha = "
                f"{k_alpha:g} 1/T* to {reach} by T* = {problem.t_end:g} (docs/model.md, Bounds): look at "
                f"params.k_alpha (Table 2: {Parameters().k_alpha:g})", self.fv.describe(cell))

    def counters(self) -> Counters:
        """The nutrient's and the biofilm's counters; upwind runs add their largest numerical diffusion."""
        found = {**self.nutrient.counters(), **self.biofilm.counters()}
        if not self.biofilm.tvd:
            found["numerical_diffusion_max"] = self.largest_numerical_diffusion
        return found

    def full(self, values: np.ndarray) -> np.ndarray:
        """Active-cell values as a grid array, NaN in obstacles."""
        return self.fv.to_full(values)
