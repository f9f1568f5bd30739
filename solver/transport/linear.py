"""Linear solvers of the transport, with what does not change between steps reused.

* `ReusedAMG`: conjugate gradients preconditioned by an algebraic multigrid
  hierarchy (pyamg, Ruge-Stueben) that is kept across time steps.  The
  nutrient matrix changes only on its diagonal, and only where the biofilm
  moves, so a stale hierarchy stays a good preconditioner; it is rebuilt when
  the iteration count exceeds both 12 and 1.6 times its count right after the last
  rebuild (measured: once per run, 6-8 CG iterations per solve at
  20^3-60^3; docs/transport.md).
* `jacobi_bicgstab`: the biofilm matrix is dominated by 1/dt, so a diagonal
  preconditioner is enough (2-5 iterations at the nominal step).

Both judge convergence by the true residual |b - A x| <= tolerance |b|, not
by the Krylov method's recursive one (which can fall far below the true
residual, or report a "breakdown" when the initial guess is already exact).
"""
from __future__ import annotations

import numpy as np
import pyamg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..counters import Counters
from ..errors import StepFailure


class ReusedAMG:
    """CG with an AMG preconditioner rebuilt only when it has gone stale."""

    def __init__(self, tolerance: float, max_iterations: int = 500, growth: float = 1.6, floor: int = 12):
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.growth = growth  # rebuild when iterations exceed growth * (iterations right after the last rebuild)
        self.floor = floor
        self.hierarchy = None
        self.fresh_iterations = None
        self.rebuilds = 0
        self.iterations = 0  # total CG iterations, for the cost report

    def counters(self, prefix: str) -> Counters:
        return {f"{prefix}_cg_iterations": self.iterations,
                f"{prefix}_amg_rebuilds": self.rebuilds}

    def _rebuild(self, matrix: sp.csr_matrix):
        self.hierarchy = pyamg.ruge_stuben_solver(matrix, max_coarse=50)
        self.rebuilds += 1

    def _cg(self, matrix, rhs, x0):
        count = [0]

        def tick(_):
            count[0] += 1

        with np.errstate(over="ignore", invalid="ignore"):  # overflow shows up in the residual check
            x, info = spla.cg(
                matrix, rhs, x0=x0, rtol=self.tolerance, atol=0.0, maxiter=self.max_iterations,
                M=self.hierarchy.aspreconditioner(cycle="V"), callback=tick,
            )
        self.iterations += count[0]
        return x, info, count[0]

    def solve(self, matrix: sp.csr_matrix, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve the SPD system `matrix x = rhs`; raises StepFailure if CG does not converge."""
        if not np.any(rhs):
            return np.zeros_like(rhs)
        if self.hierarchy is None:
            self._rebuild(matrix)
            x, info, its = self._cg(matrix, rhs, x0)
            self.fresh_iterations = its
        else:
            x, info, its = self._cg(matrix, rhs, x0)
            if info != 0 or its > max(self.floor, self.growth * self.fresh_iterations):
                self._rebuild(matrix)
                x, info, its = self._cg(matrix, rhs, x if info == 0 else x0)
                self.fresh_iterations = max(its, 1)
        if not converged(matrix, x, rhs, self.tolerance):
            raise StepFailure(not_converged("nutrient CG", matrix, x, rhs, self.tolerance, info, its,
                                            self.max_iterations))
        return x


def converged(matrix, x, rhs, tolerance: float) -> bool:
    """True residual within tolerance (relative to |rhs|), and finite (overflow counts as not converged)."""
    with np.errstate(over="ignore", invalid="ignore"):
        residual = np.linalg.norm(rhs - matrix @ x)
        return bool(np.isfinite(residual) and residual <= tolerance * np.linalg.norm(rhs))


def not_converged(method: str, matrix, x, rhs, tolerance: float, info: int, iterations: int,
                  max_iterations: int) -> str:
    """Why a solve failed the true-residual check, in words: scipy's `info` is 0 when the method met its own
    (recursive) residual, > 0 when it ran out of iterations, < 0 on a breakdown."""
    with np.errstate(over="ignore", invalid="ignore"):
        relative = np.linalg.norm(rhs - matrix @ x) / np.linalg.norm(rhs)
    if not np.isfinite(relative):
        return f"{method} did not converge: the solution overflowed after {iterations} iterations"
    residual = f"the true residual |b - A x| = {relative:.2g} |b| is above the tolerance {tolerance:.2g}"
    if info == 0:
        return (f"{method} did not converge: it stopped after {iterations} iterations on its own recursive "
                f"residual, but {residual}")
    if info > 0:
        return f"{method} did not converge in {max_iterations} iterations: {residual}"
    return f"{method} did not converge: it broke down after {iterations} iterations (scipy info {info}); {residual}"


def jacobi_bicgstab(matrix: sp.csr_matrix, rhs: np.ndarray, x0: np.ndarray, tolerance: float,
                    diagonal: np.ndarray, max_iterations: int = 1000) -> tuple[np.ndarray, int]:
    """BiCGSTAB with a Jacobi preconditioner; returns (x, iterations) or raises StepFailure."""
    if not np.any(rhs):
        return np.zeros_like(rhs), 0
    if converged(matrix, x0, rhs, tolerance):
        return x0.copy(), 0
    inverse = 1.0 / diagonal
    precondition = spla.LinearOperator(matrix.shape, matvec=lambda v: inverse * v, dtype=float)
    count = [0]

    def tick(_):
        count[0] += 1

    with np.errstate(over="ignore", invalid="ignore"):  # overflow shows up in the residual check
        x, info = spla.bicgstab(matrix, rhs, x0=x0, rtol=tolerance, atol=0.0, maxiter=max_iterations,
                                M=precondition, callback=tick)
    if not converged(matrix, x, rhs, tolerance):
        raise StepFailure(not_converged("biofilm BiCGSTAB", matrix, x, rhs, tolerance, info, count[0],
                                        max_iterations))
    return x, count[0]
