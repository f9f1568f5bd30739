"""Geometric multigrid on the structured grid: a V-cycle preconditioner for the tangent.

The grid is structured, so the coarse spaces are known exactly: Q1 on cells
of 2h, 4h, ..., nested in the fine one.  (Smoothed aggregation, which has to
discover them, is the `preconditioners.SmoothedAggregation` alternative; the
two are compared in docs/mechanics.md.)

* Prolongation: (bi/tri)linear interpolation of each displacement component
  from the coarse nodes, a Kronecker product of 1-D interpolations.  An odd
  cell count n gets ceil(n/2) coarse cells whose last one reaches past the
  domain; only its restriction to the domain matters.  Rows of nodes without
  dofs (inside obstacles) are dropped, rows of constrained dofs zeroed, so the
  coarse correction never moves a held component.
* Coarse operators: Galerkin, A_c = P^T A P, in ndim x ndim blocks (BSR):
  they inherit the coefficient jumps (biofilm/void contrast 1e4) without
  any averaging rule.
* Smoother: Chebyshev polynomials of degree 3 in D^-1 A (D the ndim x ndim
  node blocks of the diagonal), aimed at the upper part [lmax/30, 1.1 lmax]
  of its spectrum (lmax by power iteration), before and after the coarse
  correction: the V-cycle is symmetric, a valid preconditioner for CG.  Each
  degree costs one block-sparse product; per unit of work it smooths better
  than pyamg's block Gauss-Seidel, whose kernel costs several products a
  sweep (fewer CG iterations in less time: benchmarks/mechanics_linear.py).
* Coarsest level: a sparse factorisation (SuperLU: it has < `coarsest` dofs).

The transfers depend only on the mesh and the constraints and are built
once; `build(A)` recomputes the operators for a new tangent.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .mesh import StructuredMesh


def superlu(A: sp.spmatrix):
    """A sparse LU factorisation's solve (SuperLU, ordering for a symmetric pattern)."""
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve


def interpolation_1d(cells: int) -> sp.csr_matrix:
    """Linear interpolation from ceil(cells/2) coarse cells to `cells` fine ones: (cells+1, coarse+1)."""
    fine = np.arange(cells + 1)
    left = fine // 2
    odd = fine % 2 == 1
    rows = np.concatenate([fine, fine[odd]])
    cols = np.concatenate([left, left[odd] + 1])
    vals = np.concatenate([np.where(odd, 0.5, 1.0), np.full(odd.sum(), 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(cells + 1, (cells + 1) // 2 + 1))


class Level:
    """One grid of the hierarchy: operator (BSR), inverse diagonal blocks, transfers to the next."""

    def __init__(self, P: sp.bsr_matrix | None = None):
        self.P = P  # from the next coarser level
        self.R = None if P is None else P.T.tobsr(blocksize=P.blocksize[::-1])
        self.A = None
        self.Dinv = None  # (nodes, d, d) inverse diagonal blocks
        self.bounds = None  # the smoother's target interval of the spectrum of D^-1 A

    def jacobi(self, r: np.ndarray) -> np.ndarray:
        """D^-1 r (block diagonal)."""
        d = self.Dinv.shape[1]
        return np.einsum("nij,nj->ni", self.Dinv, r.reshape(-1, d)).ravel()


class Multigrid:
    """V-cycle preconditioner: `build(A)` for each new tangent, then call it on residuals."""

    def __init__(self, mesh: StructuredMesh, constrained: np.ndarray, coarsest: int, degree: int,
                 ratio: float = 30.0):
        self.d = d = mesh.ndim
        self.degree, self.ratio = degree, ratio
        self.coarse_solve = None
        self.levels = []
        shape, nodes = tuple(mesh.grid.cells_shape), mesh.nodes
        while nodes.size * d > coarsest and max(shape) > 1:
            P = interpolation_1d(shape[0])
            for n in shape[1:]:
                P = sp.kron(P, interpolation_1d(n), format="csr")
            P = P[nodes]
            used = np.flatnonzero(np.diff(P.tocsc().indptr))
            P = sp.kron(P[:, used], sp.identity(d), format="csr")
            self.levels.append(Level(P.tobsr(blocksize=(d, d))))
            shape, nodes = tuple((n + 1) // 2 for n in shape), used
        self.levels.append(Level())
        self.interpolation = self.levels[0].P if len(self.levels) > 1 else None
        self.constrain(constrained)

    def constrain(self, constrained: np.ndarray):
        """Zero the interpolation's rows of held dofs: a coarse correction never moves them."""
        if self.interpolation is None:
            return
        free = sp.diags((~np.asarray(constrained, bool)).astype(float))
        P = (free @ self.interpolation).tobsr(blocksize=self.interpolation.blocksize)
        self.levels[0] = Level(P)

    def build(self, A: sp.spmatrix):
        """Galerkin operators and smoother data for tangent A (fine level, identity at constrained dofs)."""
        d = self.d
        A = A.tobsr(blocksize=(d, d))
        for level in self.levels[:-1]:
            A.sort_indices()
            level.A, level.Dinv = A, _block_diagonal_inverse(A)
            top = 1.1 * _largest_eigenvalue(level)
            level.bounds = (top / self.ratio, top)
            A = level.R @ (A @ level.P)
            empty = A.diagonal() == 0  # coarse dofs whose support is all constrained
            if np.any(empty):
                A = (A + sp.diags(empty.astype(float))).tobsr(blocksize=(d, d))
        self.coarse_solve = superlu(A)

    def _smooth(self, level: Level, x: np.ndarray, b: np.ndarray, zero: bool = False):
        """`degree` Chebyshev steps on D^-1 A x = D^-1 b, in place (zero: x is 0, saves a product)."""
        low, high = level.bounds
        theta, delta = (high + low) / 2, (high - low) / 2
        sigma = theta / delta
        rho = 1.0 / sigma
        r = level.jacobi(b if zero else b - level.A @ x)
        step = r / theta
        for k in range(self.degree):
            x += step
            if k == self.degree - 1:
                break
            r -= level.jacobi(level.A @ step)
            rho, previous = 1.0 / (2.0 * sigma - rho), rho
            step = rho * previous * step + 2.0 * rho / delta * r

    def __call__(self, b: np.ndarray, depth: int = 0) -> np.ndarray:
        """One V-cycle from a zero guess: an approximation of A^-1 b."""
        if depth == len(self.levels) - 1:
            return self.coarse_solve(b)
        level = self.levels[depth]
        x = np.zeros_like(b)
        self._smooth(level, x, b, zero=True)
        x += level.P @ self(level.R @ (b - level.A @ x), depth + 1)
        self._smooth(level, x, b)
        return x


def _largest_eigenvalue(level: Level, iterations: int = 12) -> float:
    """Power iteration for the largest eigenvalue of D^-1 A (from a fixed start: reproducible)."""
    v = np.random.default_rng(0).standard_normal(level.A.shape[0])
    estimate = 1.0
    for _ in range(iterations):
        w = level.jacobi(level.A @ v)
        estimate = np.linalg.norm(w) / np.linalg.norm(v)
        v = w / np.linalg.norm(w)
    return float(estimate)


def _block_diagonal_inverse(A: sp.bsr_matrix) -> np.ndarray:
    d = A.blocksize[0]
    rows = np.repeat(np.arange(A.shape[0] // d), np.diff(A.indptr))
    diagonal = A.data[rows == A.indices]
    return np.ascontiguousarray(np.linalg.inv(diagonal))
