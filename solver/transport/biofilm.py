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
from ..problem import Numerics, Parameters
from .bounds import ROUNDOFF, Projection
from .finite_volume import FiniteVolumeGrid
from .front import FrontVelocity
from .kernels import advection_into, central_differences, face_gradient, face_velocity
from .linear import jacobi_bicgstab


class Velocity:
    """Face-normal growth velocity w (µm/T*) per axis from the nutrient field."""

    def __init__(self, fv: FiniteVolumeGrid, params: Parameters, gradient_floor: float,
                 held_faces: list[tuple[str, np.ndarray, float]] = ()):
        self.fv = fv
        self.r, self.k = params.r, params.k
        self.floor = gradient_floor
        self.neighbours = [fv.neighbours(axis) for axis in range(fv.grid.ndim)]
        self.below = np.stack([below for below, _ in self.neighbours]).astype(np.int64)
        self.above = np.stack([above for _, above in self.neighbours]).astype(np.int64)
        self.held_faces = []  # Dirichlet faces of the nutrient: (axis, cells beside it, their inner neighbours,
        for face, cells, value in held_faces:  # +1 on a lower face / -1 on an upper one, held value)
            axis = "xyz".index(face[0])
            below, above = self.neighbours[axis]
            lower = face[1] == "-"
            self.held_faces.append((axis, cells, above[cells] if lower else below[cells], 1.0 if lower else -1.0,
                                    value))

    def central_differences(self, q: np.ndarray) -> np.ndarray:
        """Cell gradient of q, (ndim, n); a missing neighbour takes the cell's own value (zero flux)."""
        return central_differences(q, self.below, self.above, 2.0 * self.fv.grid.spacing)

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
        for f, dn, m in zip(fv.faces, normal, magnitude):
            face_gradient(dn, m, c, f.lower, f.upper, f.axis, cell_grad, h)
        largest = max((m.max(initial=0.0) for m in magnitude), default=0.0)
        if largest * h <= ROUNDOFF * float(c.max(initial=0.0)):  # flat to round-off: no direction
            return [np.zeros_like(dn) for dn in normal], cell_grad, 0.0
        floor = self.floor * largest
        velocities = [face_velocity(c, f.lower, f.upper, dn, m, self.r, self.k, floor)
                      for f, dn, m in zip(fv.faces, normal, magnitude)]
        return velocities, cell_grad, floor


class _Pattern:
    """Fixed CSR sparsity of the biofilm matrix and where each face's entries live in it."""

    def __init__(self, fv: FiniteVolumeGrid, laplacian: sp.csr_matrix, tvd: bool):
        n = fv.n
        rows, cols = [laplacian.tocoo().row, np.arange(n)], [laplacian.tocoo().col, np.arange(n)]
        if tvd:
            for f in fv.faces:
                for cell, out in ((f.lower, f.lower_out), (f.upper, f.upper_out)):
                    ok = out >= 0
                    rows += [cell[ok], out[ok]]
                    cols += [out[ok], cell[ok]]
        r, c = np.concatenate(rows), np.concatenate(cols)
        pattern = sp.csr_matrix((np.zeros(r.size), (r, c)), shape=(n, n))
        pattern.sum_duplicates()
        pattern.sort_indices()
        self.matrix = pattern
        self.keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(pattern.indptr)) * n + pattern.indices
        self.n = n
        self.diagonal = self.position(np.arange(n), np.arange(n))
        lap = laplacian.tocoo()
        self.laplacian_positions = self.position(lap.row, lap.col)
        self.laplacian_values = lap.data

    def position(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        """Index into the CSR data array of entries (row, col), which must be in the pattern."""
        return np.searchsorted(self.keys, np.asarray(row, np.int64) * self.n + col)


class Biofilm:
    """Implicit Euler step of Eq. 34 on the active cells, matrix filled in place."""

    def __init__(self, fv: FiniteVolumeGrid, params: Parameters, numerics: Numerics, held_faces=()):
        self.fv = fv
        self.params = params
        self.tvd = numerics.advection == "tvd"
        self.tolerance = numerics.biofilm_tolerance
        self.velocity = Velocity(fv, params, numerics.gradient_floor, held_faces)
        if numerics.growth_velocity == "front" and params.r > 0:  # no growth: no front to move
            self.velocity = FrontVelocity(fv, self.velocity, numerics.front_band)
        self.pattern = _Pattern(fv, fv.laplacian, self.tvd)
        p = self.pattern
        self.diffusion = np.bincount(p.laplacian_positions, weights=-params.beta * p.laplacian_values,
                                     minlength=p.keys.size)
        self.faces, self.face_positions = [], []  # per axis: (4, m) cells and (6, m) CSR data positions
        for f in fv.faces:
            same = lambda cell: p.position(cell, cell)
            out_lower = np.where(f.lower_out >= 0, f.lower_out, f.lower)
            out_upper = np.where(f.upper_out >= 0, f.upper_out, f.upper)
            self.faces.append(np.stack([f.lower, f.upper, f.lower_out, f.upper_out]).astype(np.int64))
            self.face_positions.append(np.stack([
                same(f.lower), same(f.upper), p.position(f.upper, f.lower), p.position(f.lower, f.upper),
                p.position(f.lower, out_lower), p.position(f.upper, out_upper)]).astype(np.int64))
        self.matrix = sp.csr_matrix((np.zeros(p.keys.size), p.matrix.indices, p.matrix.indptr),
                                    shape=p.matrix.shape)  # the phi matrix, its data rewritten every step
        self.iterations = 0
        self.projection = Projection()  # what _checked projected onto [0, upper]

    def counters(self) -> Counters:
        return {"biofilm_iterations": self.iterations,
                **self.projection.counters("phi")}

    def advection(self, w: list[np.ndarray], phi: np.ndarray) -> np.ndarray:
        """CSR data of the advection operator (per unit volume) for face velocities w (kernels.advection_into)."""
        data = np.zeros(self.pattern.keys.size)
        for faces, positions, wf in zip(self.faces, self.face_positions, w):
            advection_into(data, faces, positions, np.asarray(wf, dtype=float), phi, self.fv.grid.spacing, self.tvd)
        return data

    def step(self, phi: np.ndarray, alpha: np.ndarray, w: list[np.ndarray], dt: float) -> np.ndarray:
        """phi^{n+1} from phi^n, alpha^n and face velocities (from c^n); raises StepFailure."""
        source = self.params.k_alpha * alpha
        matrix = self.matrix
        data = matrix.data
        np.add(self.diffusion, self.advection(w, phi), out=data)
        data[self.pattern.diagonal] += 1.0 / dt
        rhs = np.maximum(phi / dt + source, 0.0)  # a sink (alpha < 0, Table 1's expansion) takes at most what is there
        new, its = jacobi_bicgstab(matrix, rhs, phi, self.tolerance, data[self.pattern.diagonal])
        self.iterations += its
        return self._checked(new, upper=float(np.max(phi + dt * source, initial=0.0)))

    def _checked(self, phi: np.ndarray, upper: float) -> np.ndarray:
        """NaN and maximum-principle check; round-off within ROUNDOFF is projected onto the bounds."""
        return self.projection.checked(phi, upper, "biofilm phi", self.fv.describe)

    def numerical_diffusion(self, w: list[np.ndarray]) -> float:
        """Upwind's artificial diffusivity max |w| h / 2 (µm²/T*), to set beside beta."""
        largest = max((np.abs(x).max(initial=0.0) for x in w), default=0.0)
        return 0.5 * largest * self.fv.grid.spacing
