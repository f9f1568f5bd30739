"""Linear solves of the Newton steps: scipy's Krylov methods around a preconditioner kept while it works.

`TangentSolver.solve(A, b, rtol)` (A the tangent: a `stencil.Stencil`, or any
matrix or operator with a product) returns x with |b - A x| <= rtol |b| (the
plain residual: what inexact Newton's forcing term bounds, and what Newton's
own stopping test reads):

1. CG (`scipy.sparse.linalg.cg`): the tangent is symmetric, and positive
   definite near a stable equilibrium, where Newton works; the
   preconditioners are symmetric too.  The tangent of a grown but undeformed
   start is indefinite (compressive prestress 3 kappa alpha > mu from
   alpha ~ 0.007): Newton's first step from rest uses the stress-free tangent
   instead (newton.py).
2. If CG fails (an indefinite tangent far from equilibrium, or a V-cycle
   that is not positive on it), restarted GMRES (`scipy.sparse.linalg.gmres`,
   left preconditioned, stopping on the plain residual) from where CG
   stopped.
3. A preconditioner built from an older tangent is kept while the solve needs
   at most `Settings.rebuild_after` iterations; past that it is rebuilt from
   A (once per solve) and the solve continues from its iterate.  Before the
   caller drops the tangent it was built from, `detach` lets it keep what it
   needs in less memory (the multigrid: that tangent in single precision);
   a new snapshot's is released (`invalidate`), since it will be rebuilt.

A solve that still misses rtol is accepted if it cut the residual by
`Settings.accept_inexact` (Newton copes with inexact steps), else it raises
`LinearSolveError`.  Every iteration counts against the snapshot's budget.
"""
from __future__ import annotations

import weakref

import numpy as np
import scipy.sparse.linalg as spla

from .settings import Settings


class LinearSolveError(RuntimeError):
    """No step: the Krylov solve failed with a fresh preconditioner."""


class BudgetSpent(LinearSolveError):
    """The snapshot's Krylov iterations or preconditioner builds are spent: nothing more to try."""


class TangentSolver:
    """Krylov solves with a reused preconditioner; counts iterations and builds."""

    def __init__(self, preconditioner, settings: Settings):
        self.preconditioner = preconditioner
        self.settings = settings
        self.ready = False  # built at all
        self.source = lambda: None  # (a weak reference to) the matrix it was built from
        self.iterations = 0  # over the solver's life; the caller takes differences
        self.builds = 0
        self.reset_budget()

    @property
    def name(self) -> str:
        return f"{self.settings.krylov}+{self.preconditioner.name}"

    def reset_budget(self):
        """A new snapshot: its own Krylov iterations and preconditioner builds."""
        self.budget = self.settings.krylov_budget
        self.builds_left = self.settings.max_builds

    def invalidate(self):
        """The next solve rebuilds first (the problem changed, e.g. a new snapshot's phi); until then the
        preconditioner holds nothing (the tangent it was built from is as large as the next one)."""
        self.ready = False
        self.preconditioner.release()

    def detach(self):
        """The caller is about to drop its tangent for a newer one: the preconditioner keeps what it needs of
        it (in less memory: `Preconditioner.detach`)."""
        if self.ready:
            self.preconditioner.detach()

    def constrain(self, constrained: np.ndarray):
        """Other dofs held (the rigid-body pins moved): rebuild on the next solve."""
        self.preconditioner.constrain(constrained)
        self.invalidate()

    def _build(self, A):
        if self.builds_left <= 0:
            raise BudgetSpent(f"all {self.settings.max_builds} preconditioner builds spent")
        self.preconditioner.build(A)
        self.builds += 1
        self.builds_left -= 1
        self.ready, self.source = True, weakref.ref(A)

    def solve(self, A, b: np.ndarray, rtol: float) -> np.ndarray:
        """x with |b - A x| <= rtol |b| (or an inexact step, see the module docstring)."""
        s = self.settings
        b_norm = np.linalg.norm(b)
        if b_norm == 0:
            return np.zeros_like(b)
        if not self.ready:
            self._build(A)
        else:
            self.preconditioner.prepare(A)
        x = np.zeros_like(b)
        for attempt in ("stale", "fresh", "gmres"):
            fresh = self.source() is A
            if attempt == "stale" and fresh:
                continue
            if attempt == "fresh" and not fresh:
                self._build(A)
            limit = s.rebuild_after if attempt == "stale" else s.max_krylov
            x, done = self._krylov("gmres" if attempt == "gmres" else s.krylov, A, b, x, rtol, limit)
            residual = np.linalg.norm(b - A @ x) / b_norm
            if done and residual <= 1.5 * rtol:  # the recursive residual may drift from the true one
                return x
        if residual <= s.accept_inexact:
            return x
        raise LinearSolveError(f"{self.name} reached |r|/|b| = {residual:.2e} (wanted {rtol:.1e})")

    def _krylov(self, method: str, A, b, x0, rtol, limit):
        limit = min(limit, self.budget)
        if limit <= 0:
            raise BudgetSpent(f"all {self.settings.krylov_budget} Krylov iterations spent")
        M = spla.LinearOperator(A.shape, matvec=self.preconditioner, dtype=float)
        count = [0]

        def tick(*_):
            count[0] += 1

        if method == "cg":
            x, info = spla.cg(A, b, x0=x0, rtol=rtol, atol=0.0, maxiter=limit, M=M, callback=tick)
        else:
            restart = min(self.settings.gmres_restart, limit)
            x, info = spla.gmres(A, b, x0=x0, rtol=rtol, atol=0.0, restart=restart,
                                 maxiter=-(-limit // restart), M=M, callback=tick, callback_type="pr_norm")
        self.iterations += count[0]
        self.budget -= count[0]
        ok = info == 0 and bool(np.all(np.isfinite(x)))
        return (x if np.all(np.isfinite(x)) else x0), ok
