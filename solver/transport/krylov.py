"""The Krylov loops of the transport: CG for the nutrient, Jacobi-preconditioned BiCGSTAB for the biofilm.

Both judge convergence by the true residual |b - A x| <= tolerance |b|, not by the method's recursive one
(which can fall far below the true residual, or report a "breakdown" when the initial guess is already
exact).  Their sparse products and vector updates run on a `Team` (`solver.parallel`), each entry as the
serial numpy/scipy expression computes it; their dot products and norms are numpy's on one BLAS thread, so
the iterates do not depend on the number of threads.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import StepFailure
from ..parallel import SERIAL, Team
from ..parallel.rows import product, residual
from ..parallel.vectors import add_scaled, bicgstab_direction, bicgstab_half, bicgstab_step, cg_direction, cg_step


def pcg(matrix, rhs: np.ndarray, x: np.ndarray, precondition, target: float,
        max_iterations: int, team: Team = SERIAL) -> tuple[np.ndarray, int, float, int]:
    """Preconditioned conjugate gradients from `x` (updated in place) until the recursive residual is at most
    `target`; returns (x, iterations, the true residual's norm |rhs - matrix x|, info), which the caller
    judges (a recursion that has drifted below the true residual stops with a true residual above target);
    info is 0 when the recursive residual met target, 1 when out of iterations, -1 on a breakdown.
    A starting x whose residual exceeds |rhs| is replaced by 0: from there CG could not reduce the true
    residual to target relative to |rhs| in double precision (measured: d = 1, g = 1e10, one step dt = 1)."""
    r = residual(team, matrix, x, rhs)
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
        q = product(team, matrix, p)
        curvature = p @ q
        if not curvature > 0:  # breakdown (or NaN): not converged
            return x, iteration, size if np.isfinite(size) else np.inf, -1
        step = rz / curvature
        cg_step(team, x, r, p, q, step)
        size = float(np.linalg.norm(r))
        if size <= target:
            return x, iteration, float(np.linalg.norm(residual(team, matrix, x, rhs))), 0
        z = precondition(r)
        rz, previous = r @ z, rz
        cg_direction(team, p, z, rz / previous)
    return x, max_iterations, size, 1


def within(residual: float, target: float) -> bool:
    """A residual norm at most `target`, and finite (an overflow never converges)."""
    return bool(np.isfinite(residual) and residual <= target)


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
                    diagonal: np.ndarray, max_iterations: int = 1000, team: Team = SERIAL) -> tuple[np.ndarray, int]:
    """BiCGSTAB with a Jacobi preconditioner from x0; returns (x, iterations) or raises StepFailure.

    It stops when its recursive residual is at most tolerance |rhs|; converged if the true residual
    |rhs - matrix x| is too.  Counted in iterations begun (one that converged after its first half counts)."""
    if not np.any(rhs):
        return np.zeros_like(rhs), 0
    target = tolerance * float(np.linalg.norm(rhs))
    inverse = 1.0 / diagonal
    x = np.array(x0, dtype=float)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # overflow ends as a breakdown
        x, iterations, info = _bicgstab(matrix, rhs, x, inverse, target, max_iterations, team)
        size = float(np.linalg.norm(residual(team, matrix, x, rhs)))
    if info != 0 or not within(size, target):
        raise StepFailure(not_converged("biofilm BiCGSTAB", matrix, x, rhs, tolerance, info, iterations,
                                        max_iterations))
    return x, iterations


def _bicgstab(matrix, rhs, x, inverse, target, max_iterations, team) -> tuple[np.ndarray, int, int]:
    """Jacobi-preconditioned BiCGSTAB (van der Vorst) on x in place: (x, iterations, info) with info 0 when the
    recursive residual is at most `target`, 1 when out of iterations, -1 on a breakdown."""
    r = residual(team, matrix, x, rhs)
    if np.linalg.norm(r) <= target:
        return x, 0, 0
    shadow = r.copy()
    rho = alpha = omega = 1.0
    v, p = np.zeros_like(r), np.zeros_like(r)
    p_hat, s, s_hat = np.empty_like(r), np.empty_like(r), np.empty_like(r)
    for iteration in range(1, max_iterations + 1):
        rho, previous = shadow @ r, rho
        if rho == 0.0 or not np.isfinite(rho):
            return x, iteration, -1
        bicgstab_direction(team, p, p_hat, r, v, inverse, (rho / previous) * (alpha / omega), omega)
        v = product(team, matrix, p_hat)
        along = shadow @ v
        if along == 0.0 or not np.isfinite(along):
            return x, iteration, -1
        alpha = rho / along
        bicgstab_half(team, s, s_hat, r, v, inverse, alpha)
        if np.linalg.norm(s) <= target:
            add_scaled(team, x, alpha, p_hat)
            return x, iteration, 0
        t = product(team, matrix, s_hat)
        tt = t @ t
        if tt == 0.0 or not np.isfinite(tt):
            return x, iteration, -1
        omega = (t @ s) / tt
        bicgstab_step(team, x, r, s, t, p_hat, s_hat, alpha, omega)
        if np.linalg.norm(r) <= target:
            return x, iteration, 0
        if omega == 0.0:
            return x, iteration, -1
    return x, max_iterations, 1
