"""Geometric multigrid on the structured grid, as a preconditioner for the tangent.

Why: a sparse direct factorisation of the 3-D tangent costs O(n^2): 0.6-1 s
at 20^3 cells but 30-50 s and 3.3 GB at 40^3 (docs/mechanics.md).  Smoothed
aggregation AMG needed ~70 GMRES iterations at 40^3.  The grid is
structured, so the coarse spaces are known exactly: Q1 on cells of 2h, 4h,
..., nested in the fine one.

* Prolongation: (bi/tri)linear interpolation of each displacement component
  from the coarse nodes, a Kronecker product of 1-D interpolations.  An odd
  cell count n gets ceil(n/2) coarse cells whose last one reaches past the
  domain; only its restriction to the domain matters.  Rows of nodes without
  dofs (inside obstacles) are dropped, rows of fixed dofs zeroed, so the
  coarse correction never moves a held component.
* Coarse operators: Galerkin, A_c = P^T A P: they inherit the coefficient
  jumps (biofilm/void contrast 1e4) without any averaging rule.
* Smoother: point-block Gauss-Seidel (ndim x ndim node blocks, pyamg's
  kernel), forward before and backward after the coarse correction, so the
  V-cycle is symmetric.
* Coarsest level: a sparse direct solve (`linear.DirectSolver`).

The hierarchy's interpolation depends only on the mesh and the constraints
and is built once; `update` recomputes the operators for a new tangent.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from pyamg.amg_core import block_gauss_seidel

from .mesh import StructuredMesh


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
    """One grid of the hierarchy: its operator (BSR), block-diagonal inverse, transfer to the next."""

    def __init__(self, cells_shape, nodes, P=None):
        self.cells_shape = cells_shape
        self.nodes = nodes  # grid-node index of each dof-carrying node on this level
        self.P = P  # from the next coarser level
        self.R = None if P is None else P.T.tocsr()
        self.A = None
        self.Dinv = None


class Multigrid:
    """V-cycle preconditioner; `update(A)` for each new tangent, then call it on residuals."""

    def __init__(self, mesh: StructuredMesh, fixed: np.ndarray, coarse_solver, coarsest: int = 30_000,
                 sweeps: int = 2):
        self.d = d = mesh.ndim
        self.sweeps = sweeps
        self.coarse_solver = coarse_solver
        free = ~np.asarray(fixed, bool)
        self.levels = []
        shape, nodes = tuple(mesh.grid.cells_shape), mesh.nodes
        while nodes.size * d > coarsest and max(shape) > 1:
            coarse_shape = tuple((n + 1) // 2 for n in shape)
            P = interpolation_1d(shape[0])
            for n in shape[1:]:
                P = sp.kron(P, interpolation_1d(n), format="csr")
            P = P[nodes]
            used = np.flatnonzero(np.diff(P.tocsc().indptr))
            P = sp.kron(P[:, used], sp.identity(d), format="csr")
            if not self.levels:
                P = sp.diags(free.astype(float)) @ P
            self.levels.append(Level(shape, nodes, P.tocsr()))
            shape, nodes = coarse_shape, used
        self.levels.append(Level(shape, nodes))
        self.coarse_matrix = None

    @property
    def sizes(self) -> list[int]:
        return [level.nodes.size * self.d for level in self.levels]

    def update(self, A: sp.spmatrix):
        """Galerkin operators and smoother data for tangent A (fine level, identity at fixed dofs)."""
        d = self.d
        A = A.tocsr()
        for level in self.levels[:-1]:
            level.A = A.tobsr(blocksize=(d, d))
            level.A.sort_indices()
            level.Dinv = self._block_diagonal_inverse(level.A)
            A = (level.P.T @ (A @ level.P)).tocsr()
            empty = A.diagonal() == 0  # coarse dofs whose support is all fixed
            if np.any(empty):
                A = A + sp.diags(empty.astype(float))
        self.coarse_matrix = A
        self.coarse_solver.factor(A)

    def _block_diagonal_inverse(self, A: sp.bsr_matrix) -> np.ndarray:
        rows = np.repeat(np.arange(A.shape[0] // self.d), np.diff(A.indptr))
        diagonal = A.data[rows == A.indices]
        return np.ascontiguousarray(np.linalg.inv(diagonal))

    def _smooth(self, level: Level, x: np.ndarray, b: np.ndarray, forward: bool):
        n = level.A.shape[0] // self.d
        start, stop, step = (0, n, 1) if forward else (n - 1, -1, -1)
        for _ in range(self.sweeps):
            block_gauss_seidel(level.A.indptr, level.A.indices, level.A.data.ravel(), x, b,
                               level.Dinv.ravel(), start, stop, step, self.d)

    def cycle(self, b: np.ndarray, depth: int = 0) -> np.ndarray:
        """One V-cycle from a zero guess: an approximation of A^-1 b."""
        if depth == len(self.levels) - 1:
            return self.coarse_solver.solve(b)
        level = self.levels[depth]
        x = np.zeros_like(b)
        self._smooth(level, x, b, forward=True)
        x += level.P @ self.cycle(level.R @ (b - level.A @ x), depth + 1)
        self._smooth(level, x, b, forward=False)
        return x
