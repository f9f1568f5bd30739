"""The finite-volume grid of the transport: active cells, faces, Laplacian.

Obstacle cells are removed from the unknowns altogether: every transport
array in the time loop has one entry per *active* (non-obstacle) cell, in
FiPy's cell order.  Faces are kept per axis as pairs of active cells
(``lower``, ``upper``), together with the next cells further out along the
same axis (``lower_out``, ``upper_out``; -1 where there is none), which the
TVD limiter needs.

The Laplacian is built once by FiPy (``DiffusionTerm`` on a ``Grid2D``/
``Grid3D`` with zero coefficient on faces touching an obstacle, FiPy's
default zero flux on the outer boundary) and restricted to active cells.
It is the one matrix both the nutrient and the biofilm equations reuse.
FiPy's mesh and variables refer to each other, so the arrays they hold (a
large part of a run's peak memory: docs/transport.md, "How far one machine
goes") wait for Python's cyclic collector, which counts objects, not bytes;
on grids of `COLLECT_ABOVE` cells or more they are collected at once.
"""
from __future__ import annotations

import gc
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import describe_cell
from ..problem import Grid

COLLECT_ABOVE = 32**3  # cells: below, FiPy's garbage is small and a full collection costs a small run more


@dataclass(frozen=True)
class Faces:
    """Interior faces normal to one axis between two active cells (active indices)."""

    axis: int  # 0 = x, 1 = y, 2 = z
    lower: np.ndarray
    upper: np.ndarray
    lower_out: np.ndarray  # active neighbour of `lower` further down the axis, or -1
    upper_out: np.ndarray  # active neighbour of `upper` further up the axis, or -1


def fipy_mesh(grid: Grid):
    """FiPy Grid2D/Grid3D with the scene's cells (x fastest, as our arrays)."""
    import fipy

    if fipy.solvers.solver_suite != "scipy":  # FiPy picks its suite once, when it is first imported
        raise RuntimeError(f"FiPy uses its {fipy.solvers.solver_suite} solver suite; the solver reads FiPy's "
                           "matrices as scipy ones: set FIPY_SOLVERS=scipy before FiPy is imported (the "
                           "biostudy command and its workers do)")

    h = grid.spacing
    if grid.ndim == 2:
        nx, ny = grid.shape
        return fipy.Grid2D(nx=nx, ny=ny, dx=h, dy=h)
    nx, ny, nz = grid.shape
    return fipy.Grid3D(nx=nx, ny=ny, nz=nz, dx=h, dy=h, dz=h)


def fipy_matrix(term, var) -> sp.csr_matrix:
    """The scipy matrix FiPy builds for `term` acting on `var` (no solve)."""
    from fipy.solvers import DummySolver

    term.cacheMatrix()
    term.solve(var=var, solver=DummySolver())
    return sp.csr_matrix(term.matrix.matrix)


def open_face_mask(mesh, active: np.ndarray):
    """FiPy face mask: True where both neighbours are active (or the face is outer boundary of an active cell)."""
    ids = mesh.faceCellIDs
    first = np.asarray(ids[0].filled(0))
    second_mask = np.ma.getmaskarray(ids[1])
    second = np.asarray(ids[1].filled(0))
    return active[first] & (second_mask | active[second])


class FiniteVolumeGrid:
    """Active cells of a `Grid` with obstacles removed, their faces and Laplacian."""

    def __init__(self, grid: Grid, obstacle: np.ndarray | None = None):
        self.grid = grid
        shape = grid.cells_shape
        obstacle = np.zeros(shape, bool) if obstacle is None else np.asarray(obstacle, bool).reshape(shape)
        self.active_mask = ~obstacle  # cells_shape
        active = self.active_mask.ravel()
        self.cells = np.flatnonzero(active)  # full (FiPy) index of each active cell
        self.n = self.cells.size
        full_to_active = np.full(grid.n_cells, -1, dtype=np.int64)
        full_to_active[self.cells] = np.arange(self.n)
        self.full_to_active = full_to_active
        self.faces = [self._faces(axis) for axis in range(grid.ndim)]
        self._laplacian = None

    def _faces(self, axis: int) -> Faces:
        """Pairs of active cells adjacent along `axis` (0 = x), with their outer neighbours."""
        index = self.full_to_active.reshape(self.grid.cells_shape)
        array_axis = self.grid.ndim - 1 - axis
        n = index.shape[array_axis]

        def cut(start, stop):
            return np.take(index, np.arange(start, stop), axis=array_axis)

        lower, upper = cut(0, n - 1), cut(1, n)
        below = np.concatenate([np.full_like(cut(0, 1), -1), cut(0, n - 2)], axis=array_axis)
        above = np.concatenate([cut(2, n), np.full_like(cut(0, 1), -1)], axis=array_axis)
        keep = (lower >= 0) & (upper >= 0)
        return Faces(axis, lower[keep], upper[keep], below[keep], above[keep])

    @property
    def laplacian(self) -> sp.csr_matrix:
        """Discrete Laplacian per unit volume (1/µm²), zero flux at walls and obstacles, from FiPy."""
        if self._laplacian is None:
            import fipy

            mesh = fipy_mesh(self.grid)
            coeff = fipy.FaceVariable(mesh=mesh, value=open_face_mask(mesh, self.active_mask.ravel()).astype(float))
            var = fipy.CellVariable(mesh=mesh, value=0.0)
            matrix = fipy_matrix(fipy.DiffusionTerm(coeff=coeff), var)
            matrix = sp.diags(1.0 / np.asarray(mesh.cellVolumes)) @ matrix
            self._laplacian = sp.csr_matrix(matrix[self.cells][:, self.cells])
            self._laplacian.eliminate_zeros()
            self._laplacian.sort_indices()
            if self.grid.n_cells >= COLLECT_ABOVE:
                del mesh, coeff, var, matrix
                gc.collect()
        return self._laplacian

    def to_full(self, values: np.ndarray, fill: float = np.nan) -> np.ndarray:
        """Active-cell values -> array of ``grid.cells_shape`` with `fill` in obstacles."""
        full = np.full(self.grid.n_cells, fill, dtype=float)
        full[self.cells] = values
        return full.reshape(self.grid.cells_shape)

    def to_active(self, values: np.ndarray) -> np.ndarray:
        """Array of ``grid.cells_shape`` -> active-cell values."""
        return np.asarray(values, dtype=float).ravel()[self.cells]

    def boundary_cells(self, face: str) -> np.ndarray:
        """Active cells next to an outer face of the grid ("x-", ..., "z+"), in active indices."""
        axis = "xyz".index(face[0])
        array_axis = self.grid.ndim - 1 - axis
        index = self.full_to_active.reshape(self.grid.cells_shape)
        layer = np.take(index, 0 if face[1] == "-" else index.shape[array_axis] - 1, axis=array_axis).ravel()
        return layer[layer >= 0]

    def neighbours(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """(below, above) active neighbour of every active cell along `axis`; the cell itself at walls."""
        below = np.arange(self.n)
        above = np.arange(self.n)
        f = self.faces[axis]
        above[f.lower] = f.upper
        below[f.upper] = f.lower
        return below, above

    def describe(self, active_index: int) -> str:
        """Human-readable place of an active cell, for error messages."""
        full = int(self.cells[active_index])
        return describe_cell(np.unravel_index(full, self.grid.cells_shape), self.grid.spacing)
