"""Equilibrium of the growing biofilm at one snapshot: u at the grid nodes, p per cell.

`GrowthMechanics` owns what does not change between snapshots (mesh,
constraints, sparsity pattern, preconditioner) and the last converged state,
from which each `solve` starts (warm start).

Load stepping.  Each solve is a homotopy from the last converged state
(phi0, alpha0, u0) to the requested (phi, alpha): at s in (0, 1] both fields
are interpolated linearly and Newton starts from the previous step's u.  The
full step s = 1 is tried first; when Newton fails (an element would invert,
no descent, no convergence) the step is halved, and after a success it grows
again.  Below 1/64 of the way the solve gives up with a `MechanicsError`
naming the time and the worst cell.  As long as nothing has grown the start is
alpha = 0, u = 0, which is an equilibrium for any phi: then only alpha is stepped.

2-D scenes are in plane strain: u_z = 0 and F_zz = 1.  The biofilm still
grows in z (Jg = (1 + alpha)^3), but cannot expand there, so even uniform
growth of a free block is stressed: sigma_zz < 0 and, in the plane, the block
expands by more than alpha to relieve its volumetric stress.  (A
one-cell-thick slab free in z would be stress-free in that case, but its u_z
has no place in a dataset whose 2-D displacement has components x, y.)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import MechanicsError, describe_cell
from ..problem import Grid, MechanicsSetup, Parameters
from . import material
from .assembly import Assembler
from .constraints import boundary_fixed, pin_rigid_modes, rigid_modes
from .linear import TangentSolver
from .mesh import StructuredMesh
from .multigrid import Multigrid
from .newton import newton

SMALLEST_LOAD_STEP = 1.0 / 64


@dataclass
class MechanicsResult:
    """One snapshot's mechanics (SPEC 5 fields plus what it cost)."""

    u: np.ndarray  # grid.nodes_shape + (ndim,), components x, y[, z]; µm; NaN at nodes inside obstacles
    p: np.ndarray  # grid.cells_shape, hydrostatic Cauchy stress tr(sigma)/3, Pa; NaN in obstacle cells
    newton_iterations: int
    residual_history: list[float] = field(default_factory=list)
    seconds: float = 0.0
    info: dict = field(default_factory=dict)


class GrowthMechanics:
    """Finite-strain growth mechanics on the transport grid (SPEC 1, paper 2.1, 2.3.1, 3)."""

    def __init__(self, grid: Grid, params: Parameters, setup: MechanicsSetup, obstacle: np.ndarray | None = None,
                 coarsest: int = 30_000):
        self.grid, self.params, self.setup = grid, params, setup
        self.mesh = mesh = StructuredMesh(grid, obstacle)
        if mesh.n_elements == 0:
            raise ValueError("every cell is an obstacle: nothing to deform")
        fixed = boundary_fixed(mesh, setup.clamp, setup.slide)
        self.fixed, self.pins = pin_rigid_modes(mesh, fixed)
        self.assembler = Assembler(mesh, self.fixed)
        modes = rigid_modes((mesh.node_coordinates() - mesh.node_coordinates().mean(axis=0)) / mesh.h)
        modes[self.fixed] = 0.0
        self.linear = TangentSolver(setup.linear_solver, mesh.n_dofs,
                                    lambda direct: Multigrid(mesh, self.fixed, direct, coarsest=coarsest), modes)
        # last converged state, per element / dof
        self.u = np.zeros(mesh.n_dofs)
        self.phi = None
        self.alpha = np.zeros(mesh.n_elements)
        self.tangent = None  # at the last equilibrium: the predictor of the next solve

    # -- helpers -----------------------------------------------------------------
    def _cell(self, element: int) -> str:
        index = np.unravel_index(self.mesh.cells[element], self.grid.cells_shape)
        return describe_cell(index, self.grid.spacing)

    def _element_values(self, name: str, values: np.ndarray, time_: float) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if values.shape != self.grid.cells_shape:
            raise ValueError(f"{name} has shape {values.shape}, expected {self.grid.cells_shape}")
        values = values.ravel()[self.mesh.cells]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise MechanicsError(time_, f"{name} is not finite", self._cell(int(bad[0])))
        return values

    def _evaluator(self, phi: np.ndarray, alpha: np.ndarray):
        w = material.weight(phi, self.setup.residual_stiffness)
        growth = (1.0 + alpha) ** 3
        mu, kappa = self.params.mu, self.params.kappa
        return lambda u, tangent=True: self.assembler.evaluate(u, w, growth, mu, kappa, tangent)

    def _fields(self, u: np.ndarray, pressure: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = self.grid.ndim
        full_u = np.full((int(np.prod(self.grid.nodes_shape)), d), np.nan)
        full_u[self.mesh.nodes] = u.reshape(-1, d)
        full_p = np.full(self.grid.n_cells, np.nan)
        full_p[self.mesh.cells] = pressure
        return full_u.reshape(self.grid.nodes_shape + (d,)), full_p.reshape(self.grid.cells_shape)

    # -- the solve -----------------------------------------------------------------
    def solve(self, phi: np.ndarray, alpha: np.ndarray, time: float) -> MechanicsResult:
        """Equilibrium for (phi, alpha) per cell, starting from the previous call's state."""
        began = _clock()
        phi1 = self._element_values("phi", phi, time)
        alpha1 = self._element_values("alpha", alpha, time)
        if np.any(alpha1 <= -1.0):
            raise MechanicsError(time, "alpha <= -1 (no volume left)", self._cell(int(np.argmin(alpha1))))
        # with no growth yet (alpha = 0, u = 0) the start is an equilibrium for any phi: start from phi1
        phi0 = phi1 if self.phi is None or not np.any(self.alpha) else self.phi
        alpha0 = self.alpha
        tol, max_its = self.setup.newton_tolerance, self.setup.max_newton_iterations
        # force scale of the tolerance: the growth load at u = 0, reactions included (a fully
        # clamped block has no free residual at all, but its faces still carry the load)
        reference = self._evaluator(phi1, alpha1)(np.zeros_like(self.u), False).load
        builds0, gmres0 = self.linear.builds, self.linear.iterations

        u, s, ds = self.u.copy(), 0.0, 1.0
        tangent = self.tangent if np.any(alpha0) else None
        if tangent is None:  # alpha = 0, u = 0: the stress-free (linear-elastic) tangent
            tangent = self._evaluator(phi0, np.zeros_like(alpha0))(u, True).matrix
        history, iterations, steps, cutbacks = [], 0, 0, 0
        outcome = None
        if reference == 0.0:  # no growth load: the undeformed state is the equilibrium
            u = np.zeros_like(u)
            outcome = newton(self._evaluator(phi1, alpha1), self.linear.solve, u, 1.0, tol, 0)
            s = 1.0
        while s < 1.0:
            target = min(1.0, s + ds)
            evaluate = self._evaluator(phi0 + target * (phi1 - phi0), alpha0 + target * (alpha1 - alpha0))
            outcome = newton(evaluate, self.linear.solve, u, reference, tol, max_its, predictor=tangent)
            iterations += outcome.iterations
            history.extend(outcome.history)
            if outcome.converged:
                u, s, steps, tangent = outcome.u, target, steps + 1, outcome.evaluation.matrix
                ds = min(2.0 * ds, 1.0)
                continue
            cutbacks += 1
            ds /= 2.0
            if ds < SMALLEST_LOAD_STEP:
                raise self._failure(time, outcome, target)
        self._check_inversion(time, outcome.evaluation)
        self.u, self.phi, self.alpha, self.tangent = u, phi1, alpha1, outcome.evaluation.matrix
        u_grid, p_grid = self._fields(u, outcome.evaluation.pressure)
        info = {
            "linear_solver": self.linear.name,
            "load_steps": steps, "load_cutbacks": cutbacks,
            "gmres_iterations": self.linear.iterations - gmres0,
            "preconditioner_builds": self.linear.builds - builds0,
            "residual_stiffness": self.setup.residual_stiffness,
            "dofs": self.mesh.n_dofs,
            "formulation": "Q1/P0 mean dilatation" + (", plane strain" if self.grid.ndim == 2 else ""),
            "rigid_body_pins": len(self.pins),
            "min_det_F": float(outcome.evaluation.min_det.min()),
        }
        return MechanicsResult(u_grid, p_grid, iterations, history, _clock() - began, info)

    def _check_inversion(self, time_: float, evaluation):
        worst = int(np.argmin(evaluation.min_det))
        if evaluation.min_det[worst] <= 0:
            raise MechanicsError(time_, f"det F = {evaluation.min_det[worst]:.3g} <= 0 (element inverted)",
                                 self._cell(worst))

    def _failure(self, time_: float, outcome, target: float) -> MechanicsError:
        ev = outcome.evaluation
        worst = int(np.argmin(ev.min_det))
        if ev.min_det[worst] <= 0:
            cause = f"det F = {ev.min_det[worst]:.3g} <= 0 (element inverted)"
        else:  # the element around the node with the largest out-of-balance force
            node = int(np.argmax(np.abs(ev.residual).reshape(-1, self.grid.ndim).sum(axis=1)))
            worst = int(np.argmax((self.mesh.connectivity == node).any(axis=1)))
            cause = "Newton failed"
        return MechanicsError(time_, f"{cause}: {outcome.reason}; load step cut back to {target:.3g} of the "
                                     "way from the last converged state", self._cell(worst))


def _clock() -> float:
    return time.perf_counter()
