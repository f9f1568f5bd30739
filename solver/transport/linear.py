"""Linear solvers of the transport, with what does not change between steps reused.

* `ReusedAMG`: conjugate gradients preconditioned by one V-cycle of an
  algebraic multigrid hierarchy (pyamg, Ruge-Stueben) that is kept across
  time steps.  The nutrient matrix changes only on its diagonal, and only
  where the biofilm moves, so a stale hierarchy stays a good preconditioner;
  it is rebuilt when the iteration count exceeds both 12 and 1.6 times its
  count right after the last rebuild (measured: once per run; docs/transport.md).
  The V-cycle (`VCycle`) smooths the finest level on the matrix being solved,
  with one forward Gauss-Seidel sweep before the coarse correction and one
  backward sweep after: the cycle is symmetric, as CG needs, and costs half
  of pyamg's default symmetric sweeps on both sides for one iteration more.
  It passes through the first coarse level unsmoothed (see `VCycle`), and the
  hierarchy is built with `STRENGTH` down to at most `COARSEST` rows.  Each
  choice is measured before and after in docs/transport.md ("The means").
* `jacobi_bicgstab`: the biofilm matrix is dominated by 1/dt, so a diagonal
  preconditioner is enough (2-5 iterations at the nominal step).
* `KeptDiagonal`: a matrix that changes only on its diagonal, kept in CSR and
  its diagonal rewritten in place instead of a new CSR matrix built per step.

Both solvers judge convergence by the true residual |b - A x| <= tolerance |b|,
not by the Krylov method's recursive one (which can fall far below the true
residual, or report a "breakdown" when the initial guess is already exact).
"""
from __future__ import annotations

import numpy as np
import pyamg
import scipy.sparse as sp
from pyamg.amg_core import gauss_seidel

from ..counters import Counters
from ..errors import StepFailure

# The hierarchy's choices, each measured at 40^3 on a recorded run (benchmarks/nutrient.py, docs/transport.md):
COARSEST = 200  # rows of the level solved by its pseudo-inverse (pyamg's default 50 leaves one level more)
STRENGTH = ("classical", {"theta": 0.1})  # pyamg's default 0.25 coarsens the deeper levels less well here


class ReusedAMG:
    """CG with an AMG V-cycle preconditioner whose hierarchy is rebuilt only when it has gone stale."""

    def __init__(self, tolerance: float, max_iterations: int = 500, growth: float = 1.6, floor: int = 12):
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.growth = growth  # rebuild when iterations exceed growth * (iterations right after the last rebuild)
        self.floor = floor
        self.cycle: VCycle | None = None
        self.fresh_iterations = 1
        self.rebuilds = 0
        self.iterations = 0  # total CG iterations, for the cost report

    def counters(self, prefix: str) -> Counters:
        return {f"{prefix}_cg_iterations": self.iterations,
                f"{prefix}_amg_rebuilds": self.rebuilds}

    def _rebuild(self, matrix: sp.csr_matrix):
        self.cycle = VCycle(pyamg.ruge_stuben_solver(matrix, max_coarse=COARSEST, strength=STRENGTH))
        self.rebuilds += 1

    def _cg(self, matrix, rhs, x0):
        x = np.zeros_like(rhs) if x0 is None else np.array(x0, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):  # overflow shows up in the residual check
            x, its, residual, info = pcg(matrix, rhs, x, lambda r: self.cycle(matrix, r),
                                         self.tolerance * np.linalg.norm(rhs), self.max_iterations)
        self.iterations += its
        return x, residual, its, info

    def solve(self, matrix: sp.csr_matrix, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve the SPD system `matrix x = rhs`; raises StepFailure if CG does not converge."""
        if not np.any(rhs):
            return np.zeros_like(rhs)
        target = self.tolerance * float(np.linalg.norm(rhs))
        if self.cycle is None:
            self._rebuild(matrix)
            x, residual, its, info = self._cg(matrix, rhs, x0)
            self.fresh_iterations = its
        else:
            x, residual, its, info = self._cg(matrix, rhs, x0)
            if not within(residual, target) or its > max(self.floor, self.growth * self.fresh_iterations):
                self._rebuild(matrix)
                x, residual, its, info = self._cg(matrix, rhs, x if within(residual, target) else x0)
                self.fresh_iterations = max(its, 1)
        if not within(residual, target):
            raise StepFailure(not_converged("nutrient CG", matrix, x, rhs, self.tolerance, info, its,
                                            self.max_iterations))
        return x


class VCycle:
    """One V-cycle of a pyamg hierarchy as a symmetric preconditioner: per smoothed level a forward
    Gauss-Seidel sweep, the coarse correction, a backward sweep; pseudo-inverse on the coarsest level
    (pyamg's 'pinv').

    The finest level smooths on the matrix being solved (passed per call), the coarser levels keep the
    operators of the matrix the hierarchy was built from.  Levels in `passed` are not smoothed: the cycle
    goes through them, its interpolation the product of theirs (P_01 P_12 ...), its restriction the
    transpose.  Ruge-Stueben's first coarse level of a 7-point (5-point) operator is the red-black half of
    the cells with 18 (8) neighbours each, more nonzeros than the finest level in 3-D; its sweeps were a
    third of a cycle and bought no iteration (docs/transport.md), so it is passed through by default."""

    def __init__(self, hierarchy, passed: tuple[int, ...] = (1,)):
        levels = hierarchy.levels
        self.operators, self.prolongations = [], []
        index = 0
        while index < len(levels) - 1:
            prolongation = sp.csr_matrix(levels[index].P)
            self.operators.append(sp.csr_matrix(levels[index].A))
            index += 1
            while index in passed and index < len(levels) - 1:
                prolongation = sp.csr_matrix(prolongation @ levels[index].P)
                index += 1
            self.prolongations.append(prolongation)
        self.restrictions = [sp.csr_matrix(p.T) for p in self.prolongations]
        self.coarsest = np.linalg.pinv(np.asarray(levels[-1].A.toarray()))

    def __call__(self, matrix: sp.csr_matrix, residual: np.ndarray) -> np.ndarray:
        """The correction for `residual` of `matrix` (the finest level)."""
        return self._level(0, matrix, residual)

    def _level(self, index: int, matrix: sp.csr_matrix, rhs: np.ndarray) -> np.ndarray:
        if index == len(self.operators):
            return self.coarsest @ rhs
        if index > 0:
            matrix = self.operators[index]
        n = matrix.shape[0]
        x = np.zeros_like(rhs)
        gauss_seidel(matrix.indptr, matrix.indices, matrix.data, x, rhs, 0, n, 1)
        coarse = self.restrictions[index] @ (rhs - matrix @ x)
        x += self.prolongations[index] @ self._level(index + 1, matrix, coarse)
        gauss_seidel(matrix.indptr, matrix.indices, matrix.data, x, rhs, n - 1, -1, -1)
        return x


def pcg(matrix, rhs: np.ndarray, x: np.ndarray, precondition, target: float,
        max_iterations: int) -> tuple[np.ndarray, int, float, int]:
    """Preconditioned conjugate gradients from `x` (updated in place) until the recursive residual is at most
    `target`; returns (x, iterations, the true residual's norm |rhs - matrix x|, info), which the caller
    judges (a recursion that has drifted below the true residual stops with a true residual above target);
    info is 0 when the recursive residual met target, 1 when out of iterations, -1 on a breakdown.
    A starting x whose residual exceeds |rhs| is replaced by 0: from there CG could not reduce the true
    residual to target relative to |rhs| in double precision (measured: d = 1, g = 1e10, one step dt = 1)."""
    r = rhs - matrix @ x
    size = float(np.linalg.norm(r))
    if size > np.linalg.norm(rhs):  # a start worse than none (a giant step's stale guess): start from 0
        x[:] = 0.0
        r, size = rhs.copy(), float(np.linalg.norm(rhs))
    if size <= target:
        return x, 0, size, 0
    z = precondition(r)
    p = z.copy()
    rz = r @ z
    for iteration in range(1, max_iterations + 1):
        q = matrix @ p
        curvature = p @ q
        if not curvature > 0:  # breakdown (or NaN): not converged
            return x, iteration, size if np.isfinite(size) else np.inf, -1
        step = rz / curvature
        x += step * p
        r -= step * q
        size = float(np.linalg.norm(r))
        if size <= target:
            return x, iteration, float(np.linalg.norm(rhs - matrix @ x)), 0
        z = precondition(r)
        rz, previous = r @ z, rz
        p *= rz / previous
        p += z
    return x, max_iterations, size, 1


def within(residual: float, target: float) -> bool:
    """A residual norm at most `target`, and finite (an overflow never converges)."""
    return bool(np.isfinite(residual) and residual <= target)


class KeptDiagonal:
    """A CSR matrix `base + diag(d)` for a changing d, its data rewritten in place on base's pattern.

    The nutrient matrix K + gamma diag(phi) changes only on its diagonal; building it as a sum of
    sparse matrices every step was a CSR allocation and merge (measured: 2.6 ms per step at 40^3)."""

    def __init__(self, base: sp.csr_matrix):
        base = sp.csr_matrix(base, copy=True)
        base.sum_duplicates()
        base.sort_indices()
        rows = np.repeat(np.arange(base.shape[0]), np.diff(base.indptr))
        self.diagonal = np.flatnonzero(rows == base.indices)
        if self.diagonal.size != base.shape[0]:
            raise ValueError("KeptDiagonal needs every diagonal entry stored in the base matrix")
        self.base = base.data.copy()
        self.matrix = base

    def __call__(self, diagonal: np.ndarray) -> sp.csr_matrix:
        """The matrix with diag(`diagonal`) added (the same object every call: its data is overwritten)."""
        data = self.matrix.data
        data[:] = self.base
        data[self.diagonal] += diagonal
        return self.matrix


def not_converged(method: str, matrix, x, rhs, tolerance: float, info: int, iterations: int,
                  max_iterations: int) -> str:
    """Why a solve failed the true-residual check, in words: `info` is 0 when the method met its own
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
    return f"{method} did not converge: it broke down after {iterations} iterations (info {info}); {residual}"


def jacobi_bicgstab(matrix: sp.csr_matrix, rhs: np.ndarray, x0: np.ndarray, tolerance: float,
                    diagonal: np.ndarray, max_iterations: int = 1000) -> tuple[np.ndarray, int]:
    """BiCGSTAB with a Jacobi preconditioner from x0; returns (x, iterations) or raises StepFailure.

    It stops when its recursive residual is at most tolerance |rhs|; converged if the true residual
    |rhs - matrix x| is too.  Counted in iterations begun (one that converged after its first half counts)."""
    if not np.any(rhs):
        return np.zeros_like(rhs), 0
    target = tolerance * float(np.linalg.norm(rhs))
    inverse = 1.0 / diagonal
    x = np.array(x0, dtype=float)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # overflow ends as a breakdown
        x, iterations, info = _bicgstab(matrix, rhs, x, inverse, target, max_iterations)
        size = float(np.linalg.norm(rhs - matrix @ x))
    if info != 0 or not within(size, target):
        raise StepFailure(not_converged("biofilm BiCGSTAB", matrix, x, rhs, tolerance, info, iterations,
                                        max_iterations))
    return x, iterations


def _bicgstab(matrix, rhs, x, inverse, target, max_iterations) -> tuple[np.ndarray, int, int]:
    """Jacobi-preconditioned BiCGSTAB (van der Vorst) on x in place: (x, iterations, info) with info 0 when the
    recursive residual is at most `target`, 1 when out of iterations, -1 on a breakdown."""
    r = rhs - matrix @ x
    if np.linalg.norm(r) <= target:
        return x, 0, 0
    shadow = r.copy()
    rho = alpha = omega = 1.0
    v = np.zeros_like(r)
    p = np.zeros_like(r)
    for iteration in range(1, max_iterations + 1):
        rho, previous = shadow @ r, rho
        if rho == 0.0 or not np.isfinite(rho):
            return x, iteration, -1
        p = r + (rho / previous) * (alpha / omega) * (p - omega * v)
        p_hat = inverse * p
        v = matrix @ p_hat
        along = shadow @ v
        if along == 0.0 or not np.isfinite(along):
            return x, iteration, -1
        alpha = rho / along
        s = r - alpha * v
        if np.linalg.norm(s) <= target:
            x += alpha * p_hat
            return x, iteration, 0
        s_hat = inverse * s
        t = matrix @ s_hat
        tt = t @ t
        if tt == 0.0 or not np.isfinite(tt):
            return x, iteration, -1
        omega = (t @ s) / tt
        x += alpha * p_hat + omega * s_hat
        r = s - omega * t
        if np.linalg.norm(r) <= target:
            return x, iteration, 0
        if omega == 0.0:
            return x, iteration, -1
    return x, max_iterations, 1
