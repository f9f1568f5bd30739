"""The finite-volume grid of the transport: active cells, faces, Laplacian.

Obstacle cells are removed from the unknowns altogether: every transport
array in the time loop has one entry per *active* (non-obstacle) cell, in
FiPy's cell order.  Faces are kept per axis as pairs of active cells
(``lower``, ``upper``), together with the next cells further out along the
same axis (``lower_out``, ``upper_out``; -1 where there is none), which the
TVD limiter needs.

The Laplacian is FiPy's: ``DiffusionTerm`` on a ``Grid2D``/``Grid3D`` with
zero coefficient on faces touching an obstacle, FiPy's default zero flux on
the outer boundary, restricted to active cells (`fipy_laplacian`, the
definition).  It is the one matrix both the nutrient and the biofilm
equations reuse.  A run makes it from the grid's index arithmetic with
FiPy's arithmetic, operation for operation (`laplacian`): the same CSR
matrix entry for entry (tests/test_finite_volume.py), without FiPy's
per-cell Python objects, which cost 5.9 s and 0.93 GB at 80^3 (a large
part of a run's set-up and peak: docs/transport.md, "Set-up").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..errors import describe_cell
from ..problem import Grid


@dataclass(frozen=True)
class Faces:
    """Interior faces normal to one axis between two active cells (active indices), in order of their lower
    cell: `cells` (4, m) holds lower, upper, lower_out and upper_out (int32 below 2^31 cells)."""

    axis: int  # 0 = x, 1 = y, 2 = z
    cells: np.ndarray

    @property
    def lower(self) -> np.ndarray:
        return self.cells[0]

    @property
    def upper(self) -> np.ndarray:
        return self.cells[1]

    @property
    def lower_out(self) -> np.ndarray:
        """Active neighbour of `lower` further down the axis, or -1."""
        return self.cells[2]

    @property
    def upper_out(self) -> np.ndarray:
        """Active neighbour of `upper` further up the axis, or -1."""
        return self.cells[3]


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


def fipy_laplacian(grid: Grid, active_mask: np.ndarray) -> sp.csr_matrix:
    """The Laplacian per unit volume as FiPy builds it, restricted to the active cells: the definition
    `laplacian` is held to (FIPY_SOLVERS=scipy)."""
    import fipy

    mesh = fipy_mesh(grid)
    active = np.asarray(active_mask, bool).ravel()
    coeff = fipy.FaceVariable(mesh=mesh, value=open_face_mask(mesh, active).astype(float))
    matrix = fipy_matrix(fipy.DiffusionTerm(coeff=coeff), fipy.CellVariable(mesh=mesh, value=0.0))
    matrix = sp.diags(1.0 / np.asarray(mesh.cellVolumes)) @ matrix
    cells = np.flatnonzero(active)
    found = sp.csr_matrix(matrix[cells][:, cells])
    found.eliminate_zeros()
    found.sort_indices()
    return found


def laplacian(fv: FiniteVolumeGrid) -> sp.csr_matrix:
    """`fipy_laplacian` of the grid's active cells, made from its faces with FiPy's arithmetic: a face's
    geometric coefficient is (coefficient x face area) / cell distance, (1 x h^2) / h (h / h in 2-D, where a
    face's area is its length); a cell's diagonal is the sum of minus those of the open faces where it is the
    lower cell plus the sum of those where it is the upper one (FiPy adds each group at once: each a sum of
    equal terms, in order), and every entry is divided by the cell volume ((1 x h) x h [x h]) by a product
    with its reciprocal.  Rows list their columns in increasing order (the grid's, x fastest: below along z,
    y, x, the cell, above along x, y, z); a cell whose faces are all closed has an empty row (FiPy's zero
    diagonal, eliminated)."""
    grid, n, ndim = fv.grid, fv.n, fv.grid.ndim
    h = grid.spacing
    face = (1.0 * (h * h if ndim == 3 else h)) / h
    volume = (1.0 * h) * h
    reciprocal = 1.0 / (volume * h if ndim == 3 else volume)
    sums = -face * np.arange(4)  # of 0 to 3 equal terms (in order, a sum of equal terms rounds as the product)
    columns = np.full((n, 2 * ndim + 1), -1, dtype=np.int64)
    above, below = np.zeros(n, np.int64), np.zeros(n, np.int64)  # open faces where the cell is lower / upper
    for f in fv.faces:
        columns[f.upper, ndim - 1 - f.axis] = f.lower
        columns[f.lower, ndim + 1 + f.axis] = f.upper
        above[f.lower] += 1
        below[f.upper] += 1
    diagonal = sums[above] + sums[below]
    columns[:, ndim] = np.where(diagonal != 0.0, np.arange(n), -1)
    values = np.full(columns.shape, reciprocal * face)
    values[:, ndim] = reciprocal * diagonal
    stored = columns >= 0
    indptr = np.concatenate([[0], np.cumsum(stored.sum(axis=1))])
    index = np.int32 if indptr[-1] < np.iinfo(np.int32).max and n < np.iinfo(np.int32).max else np.int64
    return sp.csr_matrix((values[stored], columns[stored].astype(index), indptr.astype(index)), shape=(n, n))


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
        self._laplacian: sp.csr_matrix | None = None

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
        kind = np.int32 if self.n < np.iinfo(np.int32).max else np.int64
        return Faces(axis, np.stack([lower[keep], upper[keep], below[keep], above[keep]]).astype(kind))

    @property
    def laplacian(self) -> sp.csr_matrix:
        """Discrete Laplacian per unit volume (1/µm²), zero flux at walls and obstacles: FiPy's (`laplacian`)."""
        if self._laplacian is None:
            self._laplacian = laplacian(self)
        return self._laplacian

    def release_laplacian(self) -> None:
        """Forget the Laplacian once the operators made from it are made (it is made again if asked for)."""
        self._laplacian = None

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

    def face_ranges(self, bounds: np.ndarray) -> list[np.ndarray]:
        """Per axis, (blocks, 2): the faces first .. last - 1 that touch a cell of each block of rows
        bounds[p] .. bounds[p + 1] - 1 (faces are in order of their lower cell, as `_faces` makes them)."""
        found = []
        for f in self.faces:
            gap = int((f.upper - f.lower).max(initial=0))
            first = np.searchsorted(f.lower, bounds[:-1] - gap)
            last = np.searchsorted(f.lower, bounds[1:])
            found.append(np.stack([first, last], axis=1).astype(np.int64))
        return found

    def places(self, active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(layer, lane) of active cells: their index along the slowest array axis (z in 3-D, y in 2-D) and
        along the next (y, x), which a team's pipelined sweeps split the rows by (`parallel.sweeps`)."""
        full = self.cells[active]
        lanes = self.grid.cells_shape[1]
        per_layer = int(np.prod(self.grid.cells_shape[1:]))
        return (full // per_layer).astype(np.int32), ((full % per_layer) * lanes // per_layer).astype(np.int32)

    def describe(self, active_index: int) -> str:
        """Human-readable place of an active cell, for error messages."""
        full = int(self.cells[active_index])
        return describe_cell(np.unravel_index(full, self.grid.cells_shape), self.grid.spacing)
