"""Equilibrium of the growing biofilm at one snapshot: u at the grid nodes, p per cell.

`GrowthMechanics` owns what does not change between snapshots (mesh,
constraints, sparsity pattern, preconditioner, pressure recovery) and the
last converged state, from which each `solve` starts (warm start): check
the input, follow the load (`loading.step_load`) and assemble the result.
As long as nothing has grown the start is alpha = 0, u = 0, an equilibrium
for any phi: then only alpha is stepped.

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
from ..parallel import SERIAL, Team
from ..parallel.blas import blas_threads
from ..problem import Grid, MechanicsSetup, Parameters
from . import constraints, material, preconditioners
from .assembly import Assembler
from .constraints import boundary_held, pin_rigid_modes, rigid_modes
from .linear import TangentSolver
from .loading import Attempts, Refused, step_load
from .mesh import StructuredMesh
from .newton import nearly_incompressible
from .pressure import PressureRecovery
from .settings import DEFAULT, Settings


@dataclass
class MechanicsResult:
    """One snapshot's mechanics (dataset fields plus what it cost)."""

    u: np.ndarray  # grid.nodes_shape + (ndim,), components x, y[, z]; µm; NaN at nodes inside obstacles
    p: np.ndarray  # grid.cells_shape, hydrostatic Cauchy stress tr(sigma)/3, Pa; NaN in obstacle cells
    newton_iterations: int
    residual_history: list[float] = field(default_factory=list)
    seconds: float = 0.0
    info: dict = field(default_factory=dict)


class GrowthMechanics:
    """Finite-strain growth mechanics on the transport grid (paper 2.1, 2.3.1, 3)."""

    def __init__(self, grid: Grid, params: Parameters, setup: MechanicsSetup, obstacle: np.ndarray | None = None,
                 settings: Settings = DEFAULT, team: Team = SERIAL):
        self.grid, self.params, self.setup, self.settings = grid, params, setup, settings
        self.mesh = mesh = StructuredMesh(grid, obstacle)
        if mesh.n_elements == 0:
            raise ValueError("every cell is an obstacle: nothing to deform")
        self.held = boundary_held(mesh, setup.clamp, setup.slide)  # by the scene: faces, obstacles
        # the reported u is pinned at the domain's corner; the solve pins where the biofilm is stiff
        self.constrained, self.pins = pin_rigid_modes(mesh, self.held)
        self.gauge_pins, self.pieces = self.pins, constraints.pieces(mesh)
        self.assembler = Assembler(mesh, self.constrained, settings.chunk, team)  # its tangents' products on `team`
        modes = rigid_modes((mesh.node_coordinates() - mesh.node_coordinates().mean(axis=0)) / mesh.h)
        self.linear = TangentSolver(preconditioners.choose(setup.linear_solver, mesh.n_dofs, mesh, self.constrained,
                                                           modes, settings), settings)
        self.pressure = PressureRecovery(mesh)
        # last converged state, per element / dof
        self.u = np.zeros(mesh.n_dofs)
        self.phi = None
        self.alpha = np.zeros(mesh.n_elements)

    def start_from(self, u: np.ndarray, phi: np.ndarray, alpha: np.ndarray) -> None:
        """Go on from a converged state of another run (a continuation): u per node as a dataset holds it
        (nodes_shape + (ndim,), NaN inside obstacles), phi and alpha per cell; the next `solve` follows the
        load from there, as it would have in that run."""
        d = self.grid.ndim
        self.u = np.nan_to_num(np.asarray(u, dtype=float)).reshape(-1, d)[self.mesh.nodes].ravel()
        self.phi = self._element_values("phi", np.nan_to_num(phi), 0.0)
        self.alpha = self._element_values("alpha", np.nan_to_num(alpha), 0.0)

    # -- helpers -----------------------------------------------------------------
    def _cell(self, element: int) -> str:
        index = np.unravel_index(self.mesh.cells[element], self.grid.cells_shape)
        return describe_cell(index, self.grid.spacing)

    def _element_values(self, name: str, values: np.ndarray, when: float) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        if values.shape != self.grid.cells_shape:
            raise ValueError(f"{name} has shape {values.shape}, expected {self.grid.cells_shape}")
        values = values.ravel()[self.mesh.cells]
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise MechanicsError(when, f"{name} is not finite", self._cell(int(bad[0])))
        return values

    def _evaluator(self, phi: np.ndarray, alpha: np.ndarray):
        w = material.weight(phi, self.setup.residual_stiffness)
        growth = (1.0 + alpha) ** 3
        mu, kappa = self.params.mu, self.params.kappa
        return lambda u, tangent=True: self.assembler.evaluate(u, w, growth, mu, kappa, tangent)

    # -- the solve -----------------------------------------------------------------
    def solve(self, phi: np.ndarray, alpha: np.ndarray, time: float) -> MechanicsResult:
        """Equilibrium for (phi, alpha) per cell, starting from the previous call's state."""
        with blas_threads(self.settings.blas_threads):
            return self._solve(phi, alpha, time)

    def _solve(self, phi: np.ndarray, alpha: np.ndarray, time: float) -> MechanicsResult:
        began = _clock()
        phi1 = self._element_values("phi", phi, time)
        alpha1 = self._element_values("alpha", alpha, time)
        if np.any(alpha1 <= -1.0):
            raise MechanicsError(time, "alpha <= -1 (no volume left)", self._cell(int(np.argmin(alpha1))))
        # with no growth yet (alpha = 0, u = 0) the start is an equilibrium for any phi: start from phi1
        phi0 = phi1 if self.phi is None or not np.any(self.alpha) else self.phi
        alpha0 = self.alpha
        # force scale of the tolerance: the growth load at u = 0, reactions included (a fully
        # clamped block has no free residual at all, but its faces still carry the load)
        reference = self.assembler.growth_load(material.weight(phi1, self.setup.residual_stiffness),
                                               (1.0 + alpha1) ** 3, self.params.kappa)
        linear = self.linear
        builds0, krylov0 = linear.builds, linear.iterations
        linear.reset_budget()
        linear.invalidate()  # a new stiffness: the old preconditioner would cost more than a new one
        self._pin_where_stiff(phi1)
        if linear.preconditioner.uses_modes:  # the softest modes: rigid motions of each dense body
            linear.preconditioner.follow(constraints.body_modes(self.mesh, phi1 > 0.5, self.constrained))
        attempts = Attempts()

        def system(s_phi: float, s_alpha: float):
            return self._evaluator(phi0 + s_phi * (phi1 - phi0), alpha0 + s_alpha * (alpha1 - alpha0))

        if reference == 0.0:  # no growth load: the undeformed state is the equilibrium
            u, evaluation = np.zeros_like(self.u), system(1.0, 1.0)(np.zeros_like(self.u), False)
        else:
            try:
                outcome = step_load(system, linear, self.u.copy(), reference, self.setup.newton_tolerance,
                                    self.setup.max_newton_iterations, self.settings, attempts)
            except Refused as refusal:
                growth = float(np.max(np.abs(alpha1 - alpha0), initial=0.0))
                raise self._refusal(time, refusal, attempts, linear.iterations - krylov0,
                                    linear.builds - builds0, growth) from None
            u, evaluation = outcome.u, outcome.evaluation
        self._check_inversion(time, evaluation)
        self.u, self.phi, self.alpha = u, phi1, alpha1
        return self._result(u, evaluation, phi1, attempts, linear.iterations - krylov0,
                            linear.builds - builds0, _clock() - began)

    def _pin_where_stiff(self, phi: np.ndarray):
        """Move the rigid-body pins into the stiffest biofilm unless they are there (constraints.py)."""
        if not self.pins or not self.settings.pin_in_biofilm:
            return
        stiffness = constraints.node_stiffness(self.mesh, material.weight(phi, self.setup.residual_stiffness))
        if constraints.pins_are_stiff(self.pins, stiffness, self.pieces):
            return
        self.constrained, self.pins = pin_rigid_modes(self.mesh, self.held, stiffness)
        self.u = constraints.gauge(self.mesh, self.u, self.held, self.pins)
        self.assembler.constrain(self.constrained)
        self.linear.constrain(self.constrained)

    def _result(self, u, evaluation, phi, attempts: Attempts, krylov: int, builds: int,
                seconds: float) -> MechanicsResult:
        """Grid fields and the report of one converged snapshot."""
        d = self.grid.ndim
        full_u = np.full((int(np.prod(self.grid.nodes_shape)), d), np.nan)
        if self.pins != self.gauge_pins:
            u = constraints.gauge(self.mesh, u, self.held, self.gauge_pins)
        full_u[self.mesh.nodes] = u.reshape(-1, d)
        element_p = evaluation.pressure
        if self.setup.pressure == "recovered":
            element_p = self.pressure.recover(element_p, material.weight(phi, self.setup.residual_stiffness))
        full_p = np.full(self.grid.n_cells, np.nan)
        full_p[self.mesh.cells] = element_p
        info = {
            "linear_solver": self.linear.name,
            "load_steps": attempts.converged, "load_cutbacks": len(attempts.steps) - attempts.converged,
            "krylov_iterations": krylov,
            "preconditioner_builds": builds,
            "residual_stiffness": self.setup.residual_stiffness,
            "dofs": self.mesh.n_dofs,
            "formulation": "Q1/P0 mean dilatation" + (", plane strain" if d == 2 else ""),
            "rigid_body_pins": len(self.pins),
            "min_det_F": float(evaluation.min_det.min()),
        }
        return MechanicsResult(full_u.reshape(self.grid.nodes_shape + (d,)), full_p.reshape(self.grid.cells_shape),
                               attempts.newton, attempts.history, seconds, info)

    def _check_inversion(self, when: float, evaluation):
        worst = int(np.argmin(evaluation.min_det))
        if evaluation.min_det[worst] <= 0:
            raise MechanicsError(when, f"det F = {evaluation.min_det[worst]:.3g} <= 0 (element inverted)",
                                 self._cell(worst))

    def _refusal(self, when: float, refusal: Refused, attempts: Attempts, krylov: int, builds: int,
                 growth: float) -> MechanicsError:
        """The diagnosis: cause, worst cell, how far the load got and what was tried."""
        outcome = refusal.outcome
        worst, cause = 0, "no Newton step was tried"
        if outcome is not None:
            ev = outcome.evaluation
            worst = int(np.argmin(ev.min_det))
            if ev.min_det[worst] <= 0:
                cause = f"det F = {ev.min_det[worst]:.3g} <= 0 (element inverted)"
            else:  # the element around the node with the largest out-of-balance force
                node = int(np.argmax(np.abs(ev.residual).reshape(-1, self.grid.ndim).sum(axis=1)))
                worst = int(np.argmax((self.mesh.connectivity == node).any(axis=1)))
                cause = "Newton failed"
            cause += f": {outcome.reason}"
        summary = (f"{refusal.why}; reached {refusal.reached:.3g} of the way from the last converged state "
                   f"(next try {refusal.target:.3g}); tried {attempts.summary()}, {krylov} Krylov iterations "
                   f"and {builds} preconditioner builds ({self.linear.name})")
        summary += nearly_incompressible(self.params.nu, self.params.kappa, self.params.mu, growth)
        tried = {"load_steps": len(attempts.steps), "newton": attempts.newton, "krylov": krylov, "builds": builds}
        return MechanicsError(when, f"{cause}; {summary}", self._cell(worst), tried)


def _clock() -> float:
    return time.perf_counter()
