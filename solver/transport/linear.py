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
* `KeptDiagonal`: a matrix that changes only on its diagonal, kept in CSR and
  its diagonal rewritten in place instead of a new CSR matrix built per step.

The Krylov loops themselves (CG here, the biofilm's BiCGSTAB) are in `krylov.py`.
On a `Team` of threads the cycle's sweeps are pipelined (`parallel.sweeps`) and its
products split in blocks of rows (`parallel.rows`): the same numbers as on one.
"""
from __future__ import annotations

import numpy as np
import pyamg
import scipy.sparse as sp

from ..counters import Counters
from ..errors import StepFailure
from ..parallel import SERIAL, Team
from ..parallel.rows import add_product, product, residual, split, with_diagonal
from ..parallel.sweeps import Sweeps
from .krylov import not_converged, pcg, within

# The hierarchy's choices, each measured at 40^3 on a recorded run (benchmarks/nutrient.py, docs/transport.md):
COARSEST = 200  # rows of the level solved by its pseudo-inverse (pyamg's default 50 leaves one level more)
STRENGTH = ("classical", {"theta": 0.1})  # pyamg's default 0.25 coarsens the deeper levels less well here


class ReusedAMG:
    """CG with an AMG V-cycle preconditioner whose hierarchy is rebuilt only when it has gone stale."""

    def __init__(self, tolerance: float, max_iterations: int = 500, growth: float = 1.6, floor: int = 12,
                 team: Team = SERIAL, places: tuple[np.ndarray, np.ndarray] | None = None):
        self.tolerance = tolerance
        self.team = team
        self.places = places  # (layer, lane) of every row on the grid: the sweeps' pipeline (VCycle)
        self.max_iterations = max_iterations
        self.growth = growth  # rebuild when iterations exceed growth * (iterations right after the last rebuild)
        self.floor = floor
        self.cycle: VCycle | None = None
        self.prepared = False  # a hierarchy built ahead (`prepare`) for the next solve, which counts as its first
        self.fresh_iterations = 1
        self.rebuilds = 0
        self.iterations = 0  # total CG iterations, for the cost report

    def counters(self, prefix: str) -> Counters:
        return {f"{prefix}_cg_iterations": self.iterations,
                f"{prefix}_amg_rebuilds": self.rebuilds}

    def _rebuild(self, matrix: sp.csr_matrix):
        self.cycle = VCycle(pyamg.ruge_stuben_solver(matrix, max_coarse=COARSEST, strength=STRENGTH),
                            team=self.team, places=self.places)
        self.rebuilds += 1

    def prepare(self, matrix: sp.csr_matrix) -> None:
        """Build the hierarchy of the next solve's matrix now (the same matrix: the solve is then as it would have
        been), while less else is held: its set-up needs the most memory of a run's start (docs/transport.md)."""
        self._rebuild(matrix)
        self.prepared = True

    def _cg(self, matrix, rhs, x0):
        x = np.zeros_like(rhs) if x0 is None else np.array(x0, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):  # overflow shows up in the residual check
            x, its, residual, info = pcg(matrix, rhs, x, lambda r: self.cycle(matrix, r),
                                         self.tolerance * np.linalg.norm(rhs), self.max_iterations, self.team)
        self.iterations += its
        return x, residual, its, info

    def solve(self, matrix: sp.csr_matrix, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Solve the SPD system `matrix x = rhs`; raises StepFailure if CG does not converge."""
        if not np.any(rhs):
            return np.zeros_like(rhs)
        target = self.tolerance * float(np.linalg.norm(rhs))
        if self.cycle is None:
            self.prepare(matrix)
        if self.prepared:  # a hierarchy built for this very matrix: its iterations are the fresh ones
            self.prepared = False
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
    (pyamg's 'pinv').  The finest level's forward sweep starts from 0 and leaves out the terms of the rows
    after each row, which are 0 (`Sweeps.forward`'s zero: the same bits).

    The finest level smooths on the matrix being solved (passed per call), the coarser levels keep the
    operators of the matrix the hierarchy was built from.  Levels in `passed` are not smoothed: the cycle
    goes through them, its interpolation the product of theirs (P_01 P_12 ...), its restriction the
    transpose.  Ruge-Stueben's first coarse level of a 7-point (5-point) operator is the red-black half of
    the cells with 18 (8) neighbours each, more nonzeros than the finest level in 3-D; its sweeps were a
    third of a cycle and bought no iteration (docs/transport.md), so it is passed through by default.

    `places` (layer, lane) of the finest rows on the grid let a team pipeline the sweeps; a coarse level's
    rows are the C-points of the level above, in its order (Ruge-Stueben's), and take their places."""

    def __init__(self, hierarchy, passed: tuple[int, ...] = (1,), team: Team = SERIAL,
                 places: tuple[np.ndarray, np.ndarray] | None = None):
        levels = hierarchy.levels
        self.team = team
        self.operators, self.prolongations, self.sweeps = [], [], []
        index = 0
        while index < len(levels) - 1:
            prolongation = sp.csr_matrix(levels[index].P)
            self.operators.append(sp.csr_matrix(levels[index].A))
            self.sweeps.append(Sweeps(self.operators[-1], *(places or (None, None)), team))
            index += 1
            places = coarse_places(levels[index - 1], places)
            while index in passed and index < len(levels) - 1:
                prolongation = sp.csr_matrix(prolongation @ levels[index].P)
                index += 1
                places = coarse_places(levels[index - 1], places)
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
        team, sweeps = self.team, self.sweeps[index]
        x = np.zeros_like(rhs)
        sweeps.forward(matrix, x, rhs, zero=index == 0)  # from x = 0: the later rows' terms left out (0.52 ms
        # against 0.65 on one thread at 40^3, 0.33 against 0.42 pipelined on two; on the coarse levels no faster)
        coarse = product(team, self.restrictions[index], residual(team, matrix, x, rhs))
        add_product(team, self.prolongations[index], self._level(index + 1, matrix, coarse), x)
        sweeps.backward(matrix, x, rhs)
        return x


def coarse_places(level, places: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The (layer, lane) of the next level's rows: those of the C-points of `level` (a pyamg level with its
    C/F `splitting`), provided its interpolation injects them in order (Ruge-Stueben's does); else None."""
    if places is None or getattr(level, "splitting", None) is None:
        return None
    coarse = np.flatnonzero(level.splitting)
    injected = sp.csr_matrix(level.P)[coarse]
    if coarse.size != level.P.shape[1] or (injected != sp.identity(coarse.size, format="csr")).nnz:
        return None
    return places[0][coarse], places[1][coarse]


class KeptDiagonal:
    """A CSR matrix `base + diag(d)` for a changing d, its diagonal rewritten in place on base's pattern.

    The nutrient matrix K + gamma diag(phi) changes only on its diagonal; building it as a sum of
    sparse matrices every step was a CSR allocation and merge (measured: 2.6 ms per step at 40^3).  Only
    base's diagonal is kept beside the matrix; `owned`: base (canonical CSR) is given over and becomes the
    matrix, its diagonal rewritten (no copy of its arrays: memory per cell)."""

    def __init__(self, base: sp.csr_matrix, team: Team = SERIAL, owned: bool = False):
        self.team = team
        if not (owned and sp.issparse(base) and base.format == "csr" and base.has_canonical_format):
            base = sp.csr_matrix(base, copy=True)
            base.sum_duplicates()
            base.sort_indices()
        rows = np.repeat(np.arange(base.shape[0]), np.diff(base.indptr))
        self.diagonal = np.flatnonzero(rows == base.indices)
        if self.diagonal.size != base.shape[0]:
            raise ValueError("KeptDiagonal needs every diagonal entry stored in the base matrix")
        self.base = base.data[self.diagonal]  # its off-diagonal entries stay as they are in the matrix
        self.matrix = base

    def __call__(self, diagonal: np.ndarray) -> sp.csr_matrix:
        """The matrix with diag(`diagonal`) added (the same object every call: its diagonal is overwritten, what
        ``data[:] = base; data[positions] += diagonal`` made)."""
        matrix, base, positions = self.matrix, self.base, self.diagonal
        diagonal = np.ascontiguousarray(diagonal, dtype=float)
        split(self.team, matrix.shape[0], lambda a, b: with_diagonal(matrix.data, base, positions, diagonal, a, b))
        return matrix
