"""Residual and consistent tangent of the Q1/P0 growth problem, vectorised over elements.

Apart from solving: given nodal displacements and per-element data (weight
w, growth Jg), return the internal-force vector, the exact tangent as a
block-sparse (BSR, ndim x ndim blocks) matrix on a pattern fixed at
construction, and per-element pressure and volume ratios.

Element quantities (mean dilatation, paper section 3 and Table 1 steps 5-7),
with g_ai = G_iJ dN_a/dX_J, f_ai = F_iJ dN_a/dX_J at each Gauss point q:

    v      = sum_q w_q J                      (current element volume)
    Theta  = v / (Jg V),   p = w kappa (Theta - 1)
    R_ai   = sum_q w_q P_iJ dN_a/dX_J,   P = s (F - I1/3 G) + p J G,   s = Jg w mu J^(-2/3)
    K      = sum_q w_q [ s d_ik (dN_a . dN_b) + c_fg (g_ai f_bk + f_ai g_bk)
                         + c_gg g_ai g_bk + c_swap g_ak g_bi ]
             + w kappa / (Jg V) h_ai h_bk,   h_ai = sum_q w_q J g_ai

The last term is the condensed pressure (Schur complement of the P0 block,
Table 1 step 7); the rest is `material.tangent_coefficients` contracted with
the gradients.  Fixed dofs get identity rows and columns so that the matrix
stays symmetric.

Assembly uses the grid: element matrices are added into a node x stencil
array (27 neighbours in 3-D, 9 in 2-D) one local node pair (a, b) at a time,
each a shifted slice of the cell grid (no index arrays, no sorting), and the
BSR data are one gather from it.  Work goes in slabs of grid planes to bound
the temporaries.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from . import material
from .mesh import StructuredMesh


@dataclass
class Evaluation:
    """One evaluation at a displacement: everything Newton and the output need."""

    residual: np.ndarray  # (dofs,), zero at constrained dofs
    matrix: sp.bsr_matrix | None  # consistent tangent, identity at constrained dofs
    pressure: np.ndarray  # (elements,) Cauchy hydrostatic stress p = w kappa (Theta - 1), Pa
    min_det: np.ndarray  # (elements,) smallest det F over Gauss points and corners
    energy: float


class Assembler:
    """Assembles on a fixed pattern; `constrained` marks dofs held at zero."""

    def __init__(self, mesh: StructuredMesh, constrained: np.ndarray, chunk: int = 4096):
        self.mesh = mesh
        self.d = d = mesh.ndim
        self.ref = ref = mesh.reference
        self.edofs = mesh.element_dofs()
        nloc = ref.gradients.shape[1]
        self._pattern()
        self.constrain(constrained)
        cells = mesh.grid.cells_shape
        self.plane = plane = int(np.prod(cells[1:]))  # elements per grid plane (cells, obstacles included)
        self.planes = max(1, chunk // plane)  # grid planes per slab
        # first element of every plane (elements are the open cells in grid order)
        self.plane_start = np.searchsorted(mesh.cells, np.arange(cells[0] + 1) * plane)
        Q = ref.gradients.shape[0]
        # constant per element: w_q dN_a . dN_b (the isotropic part), w_q dN_a/dX_J (the residual)
        self.gram = np.einsum("q,qaJ,qbJ->qab", ref.weights, ref.gradients, ref.gradients).reshape(Q, -1)
        self.weighted_dN = (ref.weights[:, None, None] * ref.gradients).transpose(0, 2, 1).reshape(Q * d, nloc)
        # displacement -> gradient at the Gauss points / corners: (nloc, Q * d) each
        self.to_points = ref.gradients.transpose(1, 0, 2).reshape(nloc, -1)
        self.to_corners = ref.corner_gradients.transpose(1, 0, 2).reshape(nloc, -1)

    def _pattern(self):
        """The BSR pattern from the grid: node x stencil slot, occupied where an open cell links them."""
        mesh, d = self.mesh, self.d
        cells, nodes = mesh.grid.cells_shape, mesh.grid.nodes_shape
        corners = mesh.reference.corners[:, ::-1]  # (a, [z,] y, x)
        self.slots = 3**d
        strides = np.array([int(np.prod(nodes[k + 1:])) for k in range(d)])
        self.pairs = []  # (a, b, where node a sits relative to the cell, stencil slot of b from a)
        for a, ca in enumerate(corners):
            for b, cb in enumerate(corners):
                slot = int(np.dot(cb - ca + 1, 3 ** np.arange(d - 1, -1, -1)))
                self.pairs.append((a, b, tuple(slice(c, c + n) for c, n in zip(ca, cells)), slot))
        occupied = np.zeros(nodes + (self.slots,), bool)
        for _, _, at, slot in self.pairs:
            occupied[at + (slot,)] |= ~mesh.obstacle
        self.gather = np.flatnonzero(occupied)  # rows sorted, and columns within a row (slot order)
        row_grid, slot = np.divmod(self.gather, self.slots)
        offsets = np.array(np.unravel_index(np.arange(self.slots), (3,) * d)).T - 1
        col_grid = row_grid + offsets[slot] @ strides
        self.rows = mesh.grid_to_mesh_node[row_grid]
        self.indices = mesh.grid_to_mesh_node[col_grid].astype(np.int32)
        self.indptr = np.searchsorted(self.rows, np.arange(mesh.n_nodes + 1)).astype(np.int32)

    def constrain(self, constrained: np.ndarray):
        """Hold the dofs `constrained` at zero: their rows and columns become the identity's."""
        d = self.d
        self.constrained = np.asarray(constrained, bool)
        constrained_node = self.constrained.reshape(-1, d)
        self.keep = ~constrained_node[self.rows][:, :, None] & ~constrained_node[self.indices][:, None, :]
        diag = np.flatnonzero(self.rows == self.indices)
        node, comp = np.nonzero(constrained_node)
        self.constrained_diagonal = (diag[node], comp)

    def gradient(self, u: np.ndarray, elements: slice, corners: bool = False) -> np.ndarray:
        """F = I + grad u at the Gauss points (or the corners) of some elements: (E, Q, 3, 3)."""
        d = self.d
        nloc = self.to_points.shape[0]
        ue = u[self.edofs[elements]].reshape(-1, nloc, d).transpose(0, 2, 1).reshape(-1, nloc)  # (E d, a)
        H = ue @ (self.to_corners if corners else self.to_points)
        H = H.reshape(-1, d, H.shape[1] // d, d).transpose(0, 2, 1, 3)  # (E, Q, i, J)
        F = np.zeros(H.shape[:2] + (3, 3))
        F[..., :d, :d] = H
        F[..., [0, 1, 2], [0, 1, 2]] += 1.0
        return F

    def evaluate(self, u: np.ndarray, w: np.ndarray, growth: np.ndarray, mu: float, kappa: float,
                 tangent: bool = True) -> Evaluation:
        """Residual (and tangent) at displacement u; w and growth Jg = (1+alpha)^3 per element."""
        mesh, d, ref = self.mesh, self.d, self.ref
        E, nloc = mesh.n_elements, self.to_points.shape[0]
        V, wq = ref.volume, ref.weights
        forces = np.zeros((E, nloc, d))
        stencil = np.zeros(mesh.grid.nodes_shape + (self.slots, d, d)) if tangent else None
        pressure, min_det = np.zeros(E), np.empty(E)
        energy = 0.0
        n_planes = mesh.grid.cells_shape[0]
        for first in range(0, n_planes, self.planes):
            last = min(first + self.planes, n_planes)
            part = slice(self.plane_start[first], self.plane_start[last])
            if part.start == part.stop:
                continue
            F = self.gradient(u, part)
            J = material.determinant(F)
            min_det[part] = np.minimum(J.min(axis=1), material.determinant(self.gradient(u, part, True)).min(axis=1))
            if np.any(J <= 0):  # leave the rest undefined: the caller rejects this state
                continue
            G = material.cofactor(F) / J[..., None, None]
            I1 = np.einsum("eqiJ,eqiJ->eq", F, F)
            we, Jg = w[part], growth[part]
            th = J @ wq / (Jg * V)
            p = we * kappa * (th - 1.0)
            pressure[part] = p
            shear = (Jg * we * mu)[:, None]
            energy += float((material.isochoric_energy(J, I1, shear) @ wq).sum()
                            + (Jg * V * we * kappa / 2 * (th - 1.0) ** 2).sum())
            s, c_fg, c_gg, c_swap = material.tangent_coefficients(J, I1, shear, p[:, None])
            Fd, Gd = F[..., :d, :d], G[..., :d, :d]
            stress = s[..., None, None] * (Fd - (I1 / 3)[..., None, None] * Gd) + (p[:, None] * J)[..., None, None] * Gd
            # R_ai = sum_(q, J) P_iJ w_q dN_aJ: one product over (q, J)
            n = stress.shape[0]
            forces[part] = (stress.transpose(0, 2, 1, 3).reshape(n * d, -1) @ self.weighted_dN
                            ).reshape(n, d, nloc).transpose(0, 2, 1)
            if tangent:
                K = self._element_matrices(Fd, Gd, J, s, c_fg, c_gg, c_swap, we * kappa / (Jg * V))
                self._scatter(stencil, K, part, first, last)
        residual = np.bincount(self.edofs.ravel(), weights=forces.ravel(), minlength=mesh.n_dofs)
        residual[self.constrained] = 0.0
        matrix = self._matrix(stencil) if tangent and np.all(min_det > 0) else None
        return Evaluation(residual, matrix, pressure, min_det, energy)

    def growth_load(self, w: np.ndarray, growth: np.ndarray, kappa: float) -> float:
        """|internal forces| at u = 0, reactions included: the force scale of Newton's tolerance.

        At u = 0, F = G = I: the isochoric stress vanishes and P = p I with
        p = w kappa (1/Jg - 1), so R_ai = p sum_q w_q dN_a/dX_i per element."""
        corner_forces = self.weighted_dN.reshape(-1, self.d, self.weighted_dN.shape[1]).sum(axis=0).T  # (a, i)
        p = w * kappa * (1.0 / growth - 1.0)
        forces = p[:, None, None] * corner_forces
        return float(np.linalg.norm(np.bincount(self.edofs.ravel(), weights=forces.ravel(),
                                                minlength=self.mesh.n_dofs)))

    def _vectors(self, T: np.ndarray) -> np.ndarray:
        """T_iJ dN_a/dX_J at every point, as (E, Q, a * d + i): the element dof order."""
        dN = self.ref.gradients
        E, Q, d = T.shape[0], T.shape[1], self.d
        out = np.empty((E, Q, dN.shape[1], d))
        for q in range(Q):  # (E i, J) x (J, a): one small product per point
            out[:, q] = (T[:, q].reshape(E * d, d) @ dN[q].T).reshape(E, d, -1).transpose(0, 2, 1)
        return out.reshape(E, Q, -1)

    def _element_matrices(self, Fd, Gd, J, s, c_fg, c_gg, c_swap, bulk) -> np.ndarray:
        """(E, a, b, i, k) element tangents from the per-point vectors (see module docstring)."""
        E, d = Fd.shape[0], self.d
        wq = self.ref.weights
        f, g = self._vectors(Fd), self._vectors(Gd)
        nloc = g.shape[2] // d
        # sum_q [g f]_q [[c_gg, c_fg], [c_fg, 0]]_q [g f]_q^T as one batched product over 2Q: (E, ai, bk)
        left = np.concatenate([g, f], axis=1)
        right = np.concatenate([(wq * c_gg)[..., None] * g + (wq * c_fg)[..., None] * f,
                                (wq * c_fg)[..., None] * g], axis=1)
        main = np.matmul(left.transpose(0, 2, 1), right).reshape(E, nloc, d, nloc, d)
        # c_swap g_ak g_bi: the same outer product with the component indices exchanged: (E, ak, bi)
        swap = np.matmul(g.transpose(0, 2, 1), (wq * c_swap)[..., None] * g).reshape(E, nloc, d, nloc, d)
        K = np.add(main.transpose(0, 1, 3, 2, 4), swap.transpose(0, 1, 3, 4, 2))
        # s d_ik (dN_a . dN_b)
        iso = (s @ self.gram).reshape(E, nloc, nloc)
        for i in range(d):
            K[..., i, i] += iso
        # condensed pressure: rank one per element
        h = np.einsum("q,eq,eqm->em", wq, J, g).reshape(E, nloc, d)
        K += (bulk[:, None, None] * h)[:, :, None, :, None] * h[:, None, :, None, :]
        return K

    def _scatter(self, stencil: np.ndarray, K: np.ndarray, elements: slice, first: int, last: int):
        """Add the element matrices (E, a, b, i, k) of grid planes [first, last) into the stencil array."""
        cells, plane = self.mesh.grid.cells_shape, self.plane
        slab_shape = (last - first,) + cells[1:]
        if K.shape[0] == (last - first) * plane:  # no obstacle in the slab: elements are its cells
            slab = K.reshape(slab_shape + K.shape[1:])
        else:
            slab = np.zeros((int(np.prod(slab_shape)),) + K.shape[1:])
            slab[self.mesh.cells[elements] - first * plane] = K
            slab = slab.reshape(slab_shape + K.shape[1:])
        for a, b, at, slot in self.pairs:
            rows = (slice(at[0].start + first, at[0].start + last),) + at[1:]
            stencil[rows + (slot,)] += slab[..., a, b, :, :]

    def _matrix(self, stencil: np.ndarray) -> sp.bsr_matrix:
        d, n = self.d, self.mesh.n_dofs
        data = stencil.reshape(-1, d, d)[self.gather]
        data *= self.keep
        data[self.constrained_diagonal[0], self.constrained_diagonal[1], self.constrained_diagonal[1]] = 1.0
        return sp.bsr_matrix((data, self.indices, self.indptr), shape=(n, n))
