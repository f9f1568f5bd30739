"""Geometric multigrid on the structured grid: a V-cycle preconditioner for the tangent.

The grid is structured, so the coarse spaces are known exactly: Q1 on cells
of 2h, 4h, ..., nested in the fine one.  (Smoothed aggregation, which has to
discover them, is the `preconditioners.SmoothedAggregation` alternative; the
two are compared in docs/mechanics.md.)

* Prolongation: (bi/tri)linear interpolation of each displacement component
  from the coarse nodes (`transfer.py`).  An odd cell count n gets ceil(n/2)
  coarse cells whose last one reaches past the domain; only its restriction
  to the domain matters.  Nodes without dofs (inside obstacles) take no
  part, held components are not interpolated to, so the coarse correction
  never moves them.  A coarse grid's unknowns are its nodes that some fine
  node interpolates from.  Applied node by node, never stored.
* Coarse operators: Galerkin, A_c = P^T A P, in ndim x ndim blocks, kept as
  half stencils like the tangent (`stencil.py`): they inherit the coefficient
  jumps (biofilm/void contrast 1e4) without any averaging rule.  A coarse
  unknown whose support is all held gets a unit diagonal.
* Smoother: Chebyshev polynomials of degree 3 in D^-1 A (D the ndim x ndim
  node blocks of the diagonal), aimed at the upper part [lmax/30, 1.1 lmax]
  of its spectrum (lmax by power iteration), before and after the coarse
  correction: the V-cycle is symmetric, a valid preconditioner for CG.  Each
  degree costs one stencil product; per unit of work it smooths better
  than pyamg's block Gauss-Seidel, whose kernel costs several products a
  sweep (fewer CG iterations in less time: benchmarks/mechanics_linear.py).
* Coarsest level: a sparse factorisation (SuperLU: it has < `coarsest` dofs).

* Kept while it works (`linear.py`): a V-cycle built from one tangent also
  serves the next Newton steps' tangents.  It smooths on the tangent it was
  built from; once the solver drops that tangent for a newer one, the
  V-cycle keeps its own copy rounded to single precision (`detach`), so that
  two tangents in double precision are never held at once.  The rounding
  (relative 6e-8) changes only how well a stale V-cycle preconditions, not
  what the Krylov solve converges to.

The grids and their unknowns depend only on the mesh and are found once;
`build(A)` recomputes the operators for a new tangent.  Memory: the coarse
stencils hold about 1/7 of the fine one's blocks, the smoother's inverse
diagonal blocks d^2 numbers per node (docs/mechanics.md, "Memory").
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import transfer
from .mesh import StructuredMesh
from .stencil import Stencil, grid3


def superlu(A: sp.spmatrix):
    """A sparse LU factorisation's solve (SuperLU, ordering for a symmetric pattern)."""
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A").solve


class Level:
    """One grid of the hierarchy: its nodes with unknowns, operator, inverse diagonal blocks, smoother bounds."""

    def __init__(self, nodes_shape: tuple[int, ...], node_of: np.ndarray, nodes: np.ndarray, cells: tuple[int, ...]):
        self.nodes_shape = tuple(nodes_shape)
        self.node_of = node_of  # (grid nodes,) unknowns' block of each node, -1 without
        self.nodes = nodes  # (blocks,) grid node of each block
        self.cells = cells
        self.A: Stencil | None = None
        self.Dinv = None  # (nodes, d, d) inverse diagonal blocks
        self.bounds = None  # the smoother's target interval of the spectrum of D^-1 A

    def jacobi(self, r: np.ndarray) -> np.ndarray:
        """D^-1 r (block diagonal)."""
        d = self.Dinv.shape[1]
        return np.einsum("nij,nj->ni", self.Dinv, r.reshape(-1, d)).ravel()


class Multigrid:
    """V-cycle preconditioner: `build(A)` for each new tangent (a `Stencil` on the mesh's nodes), then call it on
    residuals."""

    def __init__(self, mesh: StructuredMesh, constrained: np.ndarray, coarsest: int, degree: int,
                 ratio: float = 30.0):
        self.d = d = mesh.ndim
        self.degree, self.ratio = degree, ratio
        self.coarse_solve = None
        shape, nodes_shape = tuple(mesh.grid.cells_shape), tuple(mesh.grid.nodes_shape)
        self.levels = [Level(nodes_shape, mesh.grid_to_mesh_node, mesh.nodes, shape)]
        while self.levels[-1].nodes.size * d > coarsest and max(shape) > 1:
            fine = self.levels[-1]
            used = transfer.parents_used(fine.nodes_shape, fine.node_of)
            nodes = np.flatnonzero(used)
            node_of = np.full(used.size, -1, dtype=np.int64)
            node_of[nodes] = np.arange(nodes.size)
            shape = tuple((n + 1) // 2 for n in shape)
            self.levels.append(Level(transfer.coarse_shape(fine.nodes_shape), node_of, nodes, shape))
        self.free = [np.ones(level.nodes.size * d) for level in self.levels]
        self.constrain(constrained)

    def constrain(self, constrained: np.ndarray):
        """Held fine dofs are not interpolated to: a coarse correction never moves them."""
        self.free[0] = (~np.asarray(constrained, bool)).astype(float)

    def build(self, A: Stencil):
        """Galerkin operators and smoother data for tangent A (fine level, identity at constrained dofs)."""
        d = self.d
        for depth, level in enumerate(self.levels[:-1]):
            level.A, level.Dinv = A, np.ascontiguousarray(np.linalg.inv(A.diagonal_blocks()))
            top = 1.1 * _largest_eigenvalue(level)
            level.bounds = (top / self.ratio, top)
            coarse = self.levels[depth + 1]
            blocks = np.zeros((coarse.node_of.size,) + A.blocks.shape[1:])
            transfer.galerkin(A.blocks, grid3(level.nodes_shape), A.offsets, level.node_of, self.free[depth],
                              grid3(coarse.nodes_shape), blocks)
            diagonal = blocks[coarse.nodes, 0].reshape(-1, d * d)[:, ::d + 1]  # coarse dofs whose support is
            empty = np.nonzero(diagonal == 0)  # all constrained: a unit diagonal
            blocks[coarse.nodes[empty[0]], 0, empty[1], empty[1]] = 1.0
            A = Stencil(blocks, coarse.nodes_shape, coarse.node_of, coarse.nodes, team=A.team)
        self.coarse_solve = superlu(A.tobsr())

    def detach(self):
        """Keep the finest operator (the tangent of the last `build`, which its owner is about to drop) in
        single precision: a V-cycle built from an older tangent smooths on that one (see the module's
        docstring), and in half the memory it no longer costs a second tangent beside the next."""
        fine = self.levels[0]
        if fine.A is not None and fine.A.blocks.dtype != np.float32:
            fine.A = fine.A.single()

    def release(self):
        """Drop the operators of the last `build` (until the next one)."""
        for level in self.levels:
            level.A = level.Dinv = level.bounds = None
        self.coarse_solve = None

    def prolong(self, depth: int, coarse_x: np.ndarray) -> np.ndarray:
        """P coarse_x: from level depth + 1 to level depth."""
        fine, coarse = self.levels[depth], self.levels[depth + 1]
        x = np.zeros(fine.nodes.size * self.d)
        transfer.prolong(self.d, coarse_x, grid3(coarse.nodes_shape), coarse.node_of, grid3(fine.nodes_shape),
                         fine.node_of, self.free[depth], x)
        return x

    def restrict(self, depth: int, x: np.ndarray) -> np.ndarray:
        """P^T x: from level depth to level depth + 1."""
        fine, coarse = self.levels[depth], self.levels[depth + 1]
        coarse_x = np.zeros(coarse.nodes.size * self.d)
        transfer.restrict(self.d, x, grid3(fine.nodes_shape), fine.node_of, self.free[depth],
                          grid3(coarse.nodes_shape), coarse.node_of, coarse_x)
        return coarse_x

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
        x += self.prolong(depth, self(self.restrict(depth, b - level.A @ x), depth + 1))
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
