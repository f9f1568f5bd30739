"""Linear solves of the Newton steps: a preconditioner kept as long as it works, GMRES around it.

The tangent changes little between Newton iterations and between snapshots
(strains ~ alpha ~ 1e-3..1e-2), so a preconditioner built from one tangent
stays good for the next ones.  `TangentSolver.solve` runs GMRES (the tangent
is symmetric but indefinite at the prestressed start, so neither CG nor
MINRES with an SPD preconditioner applies) with the current preconditioner
and rebuilds it from the current tangent only when GMRES needs more than
`rebuild_after` iterations or fails.

Preconditioners ("method"):
* "direct": a sparse factorisation of the tangent, PARDISO (pypardiso,
  symmetric indefinite, x86_64 only) or SuperLU elsewhere.  Fastest up to
  250k dofs; at 40^3 (207k dofs) a snapshot costs 40 s and 3.8 GB peak
  (docs/mechanics.md), against 30 s and 1.8 GB with multigrid at alpha = 1e-3;
  but at alpha = 1e-2 the prestressed, indefinite tangent defeats the V-cycle.
* "multigrid": `multigrid.Multigrid` V-cycles, direct solve on the coarsest
  level.  Cost grows about linearly with the dofs.
* "auto": direct when PARDISO is there and the problem has at most
  `direct_limit` dofs, multigrid otherwise.

Convergence is judged on the preconditioned residual |M (b - A x)| <= rtol |M b|,
an estimate of the relative error in u (see `gmres`).  A solve that misses
its tolerance even with a fresh preconditioner is still returned if it cut
the error estimate tenfold: Newton tolerates inexact steps.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

try:  # PARDISO from PyPI wheels (x86_64); SuperLU is the portable fallback
    import pypardiso
except ImportError:  # pragma: no cover - depends on the platform
    pypardiso = None


class DirectSolver:
    """Factor once, solve many: PARDISO if available, else SuperLU."""

    def __init__(self, backend: str = "auto"):
        if backend == "auto":
            backend = "pardiso" if pypardiso is not None else "superlu"
        if backend == "pardiso" and pypardiso is None:
            raise ValueError("pypardiso is not installed")
        self.backend = backend
        self._factor = None
        self._matrix = None
        self._pardiso = None  # one handle, reused: creating one searches the disk for MKL
        self.factorizations = 0

    def factor(self, A: sp.spmatrix):
        self.release()
        if self.backend == "pardiso":
            self._matrix = sp.triu(A, format="csr")  # symmetric indefinite: upper triangle
            self._matrix.sort_indices()
            if self._pardiso is None:
                self._pardiso = pypardiso.PyPardisoSolver(mtype=-2)
            self._factor = self._pardiso
            self._factor.factorize(self._matrix)
        else:
            self._factor = spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")
        self.factorizations += 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self.backend == "pardiso":
            return self._factor.solve(self._matrix, b)
        return self._factor.solve(b)

    def release(self):
        if self.backend == "pardiso" and self._factor is not None:
            self._factor.free_memory()
        self._factor = self._matrix = None


class LinearSolveError(RuntimeError):
    """GMRES did not reach its tolerance even with a fresh preconditioner."""


class TangentSolver:
    """GMRES with a reused preconditioner (direct factorisation or multigrid)."""

    def __init__(self, method: str, n_dofs: int, multigrid_factory, modes: np.ndarray | None = None,
                 direct_limit: int = 250_000, rebuild_after: int | None = None, max_iterations: int = 150):
        if method == "auto":
            method = "direct" if (pypardiso is not None and n_dofs <= direct_limit) or n_dofs <= 5_000 else "multigrid"
        if method not in ("direct", "multigrid"):
            raise ValueError(f"unknown linear solver {method!r}")
        self.method = method
        # a V-cycle is a rougher error estimator than a factorisation: the energy-norm error
        # was up to 3x the preconditioned residual at 20^3 (docs/mechanics.md)
        self.safety = 1.0 if method == "direct" else 0.3
        self.direct = DirectSolver()
        self.multigrid = multigrid_factory(self.direct) if method == "multigrid" else None
        # a stale factorisation shows in the iteration count (rebuild early: a PARDISO factorisation
        # costs ~25 iterations at 20^3); a V-cycle needs ~20 iterations whatever its age
        self.rebuild_after = rebuild_after or (12 if method == "direct" else 40)
        self.max_iterations = max_iterations
        self.fresh = False  # preconditioner built from the matrix being solved
        self.ready = False
        self.builds = 0
        self.iterations = 0  # GMRES iterations, all solves
        self.last_iterations = 0
        keep = np.linalg.norm(modes, axis=0) > 0 if modes is not None else []
        self.modes = modes[:, keep] if np.any(keep) else None
        self._deflation = None

    @property
    def name(self) -> str:
        coarse = f"{self.direct.backend} coarsest" if self.method == "multigrid" else self.direct.backend
        return f"gmres+{self.method}({coarse})"

    def _build(self, A: sp.spmatrix):
        if self.method == "direct":
            self.direct.factor(A)
        else:
            self.multigrid.update(A)
        self.ready, self.fresh = True, True
        self.builds += 1

    def _cycle(self, b: np.ndarray) -> np.ndarray:
        return self.direct.solve(b) if self.method == "direct" else self.multigrid.cycle(b)

    def _apply(self, r: np.ndarray) -> np.ndarray:
        """Preconditioner, with the rigid-body modes corrected exactly before and after.

        The modes removed by pinning single nodes of the soft void stay the softest
        of the tangent (eigenvalues ~1e-2 of the next ones at 20^3): a preconditioner
        built from another tangent leaves errors in them that neither the residual
        nor the energy shows.  A Galerkin correction in span(Z), Z the rigid modes
        zeroed at fixed dofs, removes them (a balancing-Neumann-Neumann-like
        two-level step, symmetric)."""
        if self._deflation is None:
            return self._cycle(r)
        Z, AZ, Einv, A = self._deflation
        x = Z @ (Einv @ (Z.T @ r))
        x += self._cycle(r - AZ @ (Einv @ (Z.T @ r)))
        return x + Z @ (Einv @ (Z.T @ (r - A @ x)))

    def _deflate(self, A):
        if self.modes is None:
            return
        AZ = A @ self.modes
        self._deflation = (self.modes, AZ, np.linalg.pinv(self.modes.T @ AZ, rcond=1e-12), A)

    def solve(self, A: sp.spmatrix, b: np.ndarray, rtol: float) -> np.ndarray:
        """x with relative error about rtol (see `gmres`); may rebuild the preconditioner from A."""
        rtol = max(rtol, 1e-8)  # below ~1e-9 GMRES stagnates in round-off
        self.fresh = False
        if not self.ready:
            self._build(A)
        A = A.tocsr()
        self._deflate(A)
        x, its, ok, achieved = self._gmres(A, b, rtol, self.max_iterations if self.fresh else self.rebuild_after)
        if not ok and not self.fresh:
            self._build(A)
            x, more, ok, achieved = self._gmres(A, b, rtol, self.max_iterations, x0=x)
            its += more
        self.last_iterations = its
        self.iterations += its
        if not ok and not achieved <= max(rtol, 1e-2) * 10:  # an inexact step is still a step
            raise LinearSolveError(f"GMRES reached only |M r|/|M b| = {achieved:.2e} "
                                   f"(wanted {rtol:.1e}) in {its} iterations")
        return x

    def _gmres(self, A, b, rtol, limit, x0=None):
        x, its, achieved, plain = gmres(A, b, self._apply, rtol * self.safety, limit, x0,
                                        residual_rtol=max(rtol, 1e-10))
        ok = bool(np.all(np.isfinite(x))) and achieved <= rtol * self.safety and plain <= max(rtol, 1e-10)
        return x, its, ok, max(achieved / self.safety, plain)


def gmres(A, b: np.ndarray, precondition, rtol: float, maxiter: int, x0=None, restart: int = 40,
          residual_rtol: float = np.inf):
    """Left-preconditioned GMRES: |M (b - A x)| <= rtol |M b| and |b - A x| <= residual_rtol |b|.

    Why both.  The biofilm/void stiffness contrast (1e4) makes the plain
    residual a poor error measure: a void displacement error of 1 % of |u|
    shows up as a relative residual of ~1e-6.  With M ~ A^-1 the
    preconditioned residual approximates the error in u itself, so rtol
    bounds the relative displacement error.  The converse also holds: M
    shrinks the stiff (biofilm) components, so a small |M r| can leave the
    plain residual, which Newton's residual test reads, unreduced; Newton then
    stagnates (measured at 40^3).  Each restart checks the plain residual and
    tightens the inner target until both hold.
    Returns (x, iterations, achieved |M r|/|M b|, achieved |r|/|b|).
    """
    x = np.zeros_like(b) if x0 is None else x0.copy()
    mb = precondition(b)
    scale, b_norm = np.linalg.norm(mb), np.linalg.norm(b)
    if scale == 0 or b_norm == 0:
        return np.zeros_like(b), 0, 0.0, 0.0
    its, target = 0, rtol
    while True:
        r = b - A @ x
        z = mb if its == 0 and x0 is None else precondition(r)
        beta = np.linalg.norm(z)
        achieved, plain = beta / scale, np.linalg.norm(r) / b_norm
        if (achieved <= rtol and plain <= residual_rtol) or its >= maxiter:
            break
        if achieved <= target:  # the plain residual lags behind: ask the inner loop for more
            target = 0.1 * achieved
        m = min(restart, maxiter - its)
        V = np.empty((m + 1, b.size))
        H = np.zeros((m + 1, m))
        cs, sn, g = np.zeros(m), np.zeros(m), np.zeros(m + 1)
        g[0], V[0] = beta, z / beta
        for k in range(m):
            w = precondition(A @ V[k])
            for j in range(k + 1):  # modified Gram-Schmidt
                H[j, k] = V[j] @ w
                w -= H[j, k] * V[j]
            H[k + 1, k] = np.linalg.norm(w)
            breakdown = H[k + 1, k] <= 1e-14 * abs(H[k, k])  # invariant Krylov space
            if not breakdown:
                V[k + 1] = w / H[k + 1, k]
            for j in range(k):  # previous Givens rotations
                H[j, k], H[j + 1, k] = cs[j] * H[j, k] + sn[j] * H[j + 1, k], -sn[j] * H[j, k] + cs[j] * H[j + 1, k]
            rho = np.hypot(H[k, k], H[k + 1, k])
            cs[k], sn[k] = H[k, k] / rho, H[k + 1, k] / rho
            H[k, k], H[k + 1, k] = rho, 0.0
            g[k], g[k + 1] = cs[k] * g[k], -sn[k] * g[k]
            its += 1
            if abs(g[k + 1]) <= target * scale or breakdown:
                break
        y = np.linalg.solve(np.triu(H[: k + 1, : k + 1]), g[: k + 1])
        x += V[: k + 1].T @ y
        if breakdown and target <= 1e-14:
            break
    return x, its, achieved, plain
