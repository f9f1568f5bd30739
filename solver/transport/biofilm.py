"""Biofilm density phi: one implicit step of paper Eq. 34.

    dphi/dt + v . grad(phi) = beta lap(phi) + k_alpha alpha,
    v = r c/(k+c) grad(c)/|grad(c)|                  (docs/model.md; Eq. 34 with Eqs. 22-23)

The growth term is advection in *non-conservative* form: the interface moves
toward the nutrient, mass is created, not carried.  On a face f between a
lower cell a and an upper cell b with face-normal velocity w_f, the finite-
volume form of v . grad(phi) in a cell P is sum_f (v.n_f)(phi_f - phi_P)/h;
FiPy writes the same operator as ``UpwindConvectionTerm(v) -
ImplicitSourceTerm(div v)`` (tests compare the two matrices).

Face velocity: w_f = r c_f/(k+c_f) (dc/dn)_f / max(|grad c|_f, floor), with
(dc/dn)_f = (c_b - c_a)/h, the tangential gradient from the mean of the two
cells' central differences (mirror values at walls and obstacles), and
floor = gradient_floor * max_f |grad c|_f: where the nutrient is flat the
direction is undefined and the velocity fades out linearly instead.  Where it
is flat everywhere to round-off (max_f |dc| <= ROUNDOFF max c, e.g. g = 0) its
gradients are solver residue and nothing grows (w = 0).

Schemes, both written in positive-coefficient form sum_N a_PN (phi_P - phi_N)
with a_PN >= 0 so that, with implicit Euler, the matrix is an M-matrix with
zero-row-sum advection: phi^{n+1} lies within [min phi^n, max(phi^n + dt
k_alpha alpha^n)] whatever the step (bounded by construction):
* "upwind": only inflow faces contribute, a = |w|/h.  Numerical diffusion
  ~ |v| h / 2, reported as `numerical_diffusion`.
* "tvd": van Leer limited face values phi_f = phi_U + psi(r)/2 (phi_D - phi_U),
  r = (phi_U - phi_UU)/(phi_D - phi_U), limiter lagged at phi^n.  The inflow
  face gives a = |w|(1 - psi/2)/h on (phi_D - phi_U); the outflow face's
  correction |w| psi/2 (phi_D - phi_U) = |w| (psi/r)/2 (phi_U - phi_UU) goes
  onto the upwind pair.  0 <= psi, psi/r <= 2 keep every a >= 0.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..counters import Counters
from ..parallel import SERIAL, Team
from ..parallel.rows import blocks, split, split_each
from ..problem import Numerics, Parameters
from .assembly import face_coefficients, face_maps, matrix_rows
from .bounds import ROUNDOFF, Projection
from .finite_volume import FiniteVolumeGrid
from .front import FrontVelocity
from .kernels import (
    ROWS,
    advection_into,
    biofilm_sources,
    central_differences,
    face_gradient,
    face_velocity,
    row_offsets,
)
from .krylov import jacobi_bicgstab


class Velocity:
    """Face-normal growth velocity w (µm/T*) per axis from the nutrient field."""

    def __init__(self, fv: FiniteVolumeGrid, params: Parameters, gradient_floor: float,
                 held_faces: list[tuple[str, np.ndarray, float]] = (), team: Team = SERIAL):
        self.fv = fv
        self.team = team
        self.r, self.k = params.r, params.k
        self.floor = gradient_floor
        neighbours = [fv.neighbours(axis) for axis in range(fv.grid.ndim)]
        kind = fv.faces[0].cells.dtype if fv.faces else np.int64
        self.below = np.stack([below for below, _ in neighbours]).astype(kind)  # (ndim, n)
        self.above = np.stack([above for _, above in neighbours]).astype(kind)
        self.held_faces = []  # Dirichlet faces of the nutrient: (axis, cells beside it, their inner neighbours,
        for face, cells, value in held_faces:  # +1 on a lower face / -1 on an upper one, held value)
            axis = "xyz".index(face[0])
            below, above = neighbours[axis]
            lower = face[1] == "-"
            self.held_faces.append((axis, cells, above[cells] if lower else below[cells], 1.0 if lower else -1.0,
                                    value))

    def central_differences(self, q: np.ndarray) -> np.ndarray:
        """Cell gradient of q, (ndim, n); a missing neighbour takes the cell's own value (zero flux)."""
        out = np.empty(self.below.shape)
        below, above, h2 = self.below, self.above, 2.0 * self.fv.grid.spacing
        split(self.team, self.fv.n, lambda a, b: central_differences(out, q, below, above, h2, a, b))
        return out

    def cell_gradient(self, c: np.ndarray) -> np.ndarray:
        """Cell gradient of the nutrient, (ndim, n): central differences, and beside a held nutrient face the
        ghost value 2 c_face - c (the held value on the face)."""
        h2 = 2.0 * self.fv.grid.spacing
        gradient = self.central_differences(c)
        for axis, cells, inner, sign, value in self.held_faces:
            ghost = 2.0 * value - c[cells]
            gradient[axis][cells] = sign * (c[inner] - ghost) / h2
        return gradient

    def __call__(self, c: np.ndarray, phi: np.ndarray | None = None) -> list[np.ndarray]:
        """Face velocities per axis; `phi` is not needed (the front velocity's signature)."""
        return self.field(c)[0]

    def field(self, c: np.ndarray) -> tuple[list[np.ndarray], np.ndarray | None, float]:
        """Face velocities per axis, the cell gradient of c they came from ((ndim, n); None when r = 0) and the
        floor of |grad c| they used (0 where nothing grows: r = 0 or a flat nutrient)."""
        fv, h = self.fv, self.fv.grid.spacing
        if self.r == 0.0:
            return [np.zeros(f.lower.size) for f in fv.faces], None, 0.0
        cell_grad = self.cell_gradient(c)
        normal = [np.empty(f.lower.size) for f in fv.faces]
        magnitude = [np.empty(f.lower.size) for f in fv.faces]
        faces, sizes = fv.faces, [dn.size for dn in normal]
        split_each(self.team, sizes, lambda k, a, b: face_gradient(normal[k], magnitude[k], c, faces[k].lower,
                                                                   faces[k].upper, faces[k].axis, cell_grad, h, a, b))
        largest = max((m.max(initial=0.0) for m in magnitude), default=0.0)
        if largest * h <= ROUNDOFF * float(c.max(initial=0.0)):  # flat to round-off: no direction
            return [np.zeros_like(dn) for dn in normal], cell_grad, 0.0
        floor = self.floor * largest
        velocities = [np.empty(f.lower.size) for f in fv.faces]
        split_each(self.team, sizes, lambda k, a, b: face_velocity(velocities[k], c, faces[k].lower, faces[k].upper,
                                                                   normal[k], magnitude[k], self.r, self.k, floor, a,
                                                                   b))
        return velocities, cell_grad, floor


def pattern(laplacian: sp.csr_matrix) -> sp.csr_matrix:
    """The biofilm matrix's sparsity: the Laplacian's and every diagonal, columns sorted, data zero.  TVD's far
    upwind cell is a face neighbour of the upwind one: its entries are in it too (`Biofilm` checks)."""
    n = laplacian.shape[0]
    found = sp.csr_matrix((np.ones(laplacian.nnz), laplacian.indices, laplacian.indptr), shape=laplacian.shape)
    found = sp.csr_matrix(found + sp.identity(n, format="csr"))
    found.sort_indices()
    found.data[:] = 0.0
    return found


def diffusion(laplacian: sp.csr_matrix, beta: float) -> tuple[float, np.ndarray]:
    """-beta lap as the biofilm matrix holds it: one value off the diagonal (every off-diagonal entry of the
    Laplacian is the same, a face's coefficient over the cell volume) and one per row on it (0 where a walled-in
    cell has none), each as np.bincount placed it before (0 + value)."""
    rows = np.repeat(np.arange(laplacian.shape[0]), np.diff(laplacian.indptr))
    on = rows == laplacian.indices
    values = np.unique(laplacian.data[~on])
    if values.size > 1:
        raise ValueError("the Laplacian's off-diagonal entries differ: not a uniform grid's")
    own = np.zeros(laplacian.shape[0])
    own[rows[on]] = 0.0 + -beta * laplacian.data[on]
    return (0.0 + -beta * float(values[0]) if values.size else 0.0), own


def offsets(pattern: sp.csr_matrix, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """Where the entries (rows[k], columns[k]) are in their rows of `pattern` (from the row's start), as uint8."""
    found = row_offsets(pattern.indptr, pattern.indices, np.asarray(rows, np.int64), np.asarray(columns, np.int64))
    if found.size and found.min() < 0:
        raise ValueError("an entry of the biofilm's advection is not in its matrix's pattern")
    return found.astype(np.uint8)


class Biofilm:
    """Implicit Euler step of Eq. 34 on the active cells, matrix filled in place."""

    def __init__(self, fv: FiniteVolumeGrid, params: Parameters, numerics: Numerics, held_faces=(),
                 team: Team = SERIAL):
        self.fv = fv
        self.team = team
        self.params = params
        self.tvd = numerics.advection == "tvd"
        self.tolerance = numerics.biofilm_tolerance
        laplacian = fv.laplacian
        self.matrix = pattern(laplacian)  # the phi matrix, its data rewritten every step
        self.velocity = Velocity(fv, params, numerics.gradient_floor, held_faces, team)
        if numerics.growth_velocity == "front" and params.r > 0:  # no growth: no front to move
            self.velocity = FrontVelocity(fv, self.velocity, numerics.front_band, team,
                                          (self.matrix.indptr, self.matrix.indices))
        n, indptr = fv.n, self.matrix.indptr
        self.diagonal = (indptr[:-1] + offsets(self.matrix, np.arange(n), np.arange(n))).astype(np.int64)
        self.neighbour, self.own = diffusion(laplacian, params.beta)
        self.faces, self.offsets = [], []  # per axis: (4, m) cells (the grid's) and (6, m) offsets in their rows
        for f in fv.faces:
            out_lower = np.where(f.lower_out >= 0, f.lower_out, f.lower)
            out_upper = np.where(f.upper_out >= 0, f.upper_out, f.upper)
            self.faces.append(f.cells)
            self.offsets.append(np.stack([
                offsets(self.matrix, row, column) for row, column in ((f.lower, f.lower), (f.upper, f.upper),
                                                                      (f.upper, f.lower), (f.lower, f.upper),
                                                                      (f.lower, out_lower), (f.upper, out_upper))]))
        self.rows = blocks(fv.n, team)  # the team's blocks of rows, and per axis the faces that touch each
        self.face_ranges = fv.face_ranges(self.rows)
        self.below, self.above, self.lower_entry, self.upper_entry, self.face_start = face_maps(
            self.faces, self.matrix.indptr, self.offsets, fv.n)  # each row's faces and entries (assembly.py)
        total = int(self.face_start[-1])
        self.inflow, self.outflow, self.forward = np.empty(total), np.empty(total), np.empty(total, np.bool_)
        self.iterations = 0
        self.projection = Projection()  # what _checked projected onto [0, upper]

    def counters(self) -> Counters:
        return {"biofilm_iterations": self.iterations,
                **self.projection.counters("phi")}

    def advection(self, w: list[np.ndarray], phi: np.ndarray) -> np.ndarray:
        """CSR data of the advection operator (per unit volume) for face velocities w (kernels.advection_into)."""
        data = np.zeros(self.matrix.nnz)
        for faces, offsets_, wf in zip(self.faces, self.offsets, w):
            advection_into(data, faces, offsets_, self.matrix.indptr, np.asarray(wf, dtype=float), phi,
                           self.fv.grid.spacing, self.tvd)
        return data

    def positions(self, axis: int) -> np.ndarray:
        """(6, m) where each face's six entries of one axis are in the matrix's data (`kernels.advection_into`)."""
        return self.matrix.indptr[self.faces[axis][ROWS]] + self.offsets[axis]

    def step(self, phi: np.ndarray, alpha: np.ndarray, w: list[np.ndarray], dt: float) -> np.ndarray:
        """phi^{n+1} from phi^n, alpha^n and face velocities (from c^n); raises StepFailure."""
        rhs, diagonal, upper = self.assemble(phi, alpha, w, dt)
        new, its = jacobi_bicgstab(self.matrix, rhs, phi, self.tolerance, diagonal, team=self.team)
        self.iterations += its
        return self._checked(new, upper=upper)

    def assemble(self, phi: np.ndarray, alpha: np.ndarray, w: list[np.ndarray],
                 dt: float) -> tuple[np.ndarray, np.ndarray, float]:
        """The step's matrix (into `self.matrix`: diffusion + advection + 1/dt on the diagonal), its right-hand
        side max(phi/dt + k_alpha alpha, 0), its diagonal and the maximum principle's upper bound max(phi + dt k_alpha
        alpha): block of rows by block of rows on the team, each entry summed as when made at once."""
        matrix, rows, faces = self.matrix, self.rows, self.face_ranges
        data, indptr, h = matrix.data, matrix.indptr, self.fv.grid.spacing
        w = [np.asarray(wf, dtype=float) for wf in w]
        rhs, diagonal, largest = np.empty(self.fv.n), np.empty(self.fv.n), np.zeros(rows.size - 1)
        reciprocal, k_alpha = 1.0 / dt, self.params.k_alpha

        def block(p: int) -> None:
            if p + 1 >= rows.size:
                return
            start, stop = int(rows[p]), int(rows[p + 1])
            for axis, wf in enumerate(w):
                face_coefficients(self.inflow, self.outflow, self.forward, int(self.face_start[axis]),
                                  self.faces[axis], wf, phi, h, self.tvd, faces[axis][p, 0], faces[axis][p, 1])
            matrix_rows(data, indptr, self.diagonal, self.neighbour, self.own, reciprocal, diagonal, self.below,
                        self.above, self.lower_entry, self.upper_entry, self.inflow, self.outflow, self.forward,
                        self.tvd, start, stop)
            largest[p] = biofilm_sources(rhs, phi, alpha, k_alpha, dt, start, stop)

        self.team.run(block) if rows.size > 2 else block(0)
        return rhs, diagonal, float(np.max(largest))

    def _checked(self, phi: np.ndarray, upper: float) -> np.ndarray:
        """NaN and maximum-principle check; round-off within ROUNDOFF is projected onto the bounds."""
        return self.projection.checked(phi, upper, "biofilm phi", self.fv.describe)

    def numerical_diffusion(self, w: list[np.ndarray]) -> float:
        """Upwind's artificial diffusivity max |w| h / 2 (µm²/T*), to set beside beta."""
        largest = max((np.abs(x).max(initial=0.0) for x in w), default=0.0)
        return 0.5 * largest * self.fv.grid.spacing
