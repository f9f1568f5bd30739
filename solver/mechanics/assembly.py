"""Residual and consistent tangent of the Q1/P0 growth problem, vectorised over elements.

Apart from solving: given nodal displacements and per-element data (weight
w, growth Jg), return the internal-force vector, the exact tangent as a
block-sparse (BSR, ndim x ndim blocks) matrix on a pattern fixed at
construction, and per-element pressure and volume ratios.

Element quantities (mean dilatation, paper 3 and Table 1 steps 5-7), with
g_ai = G_iJ dN_a/dX_J, f_ai = F_iJ dN_a/dX_J at each Gauss point q:

    v      = sum_q w_q J                      (current element volume)
    Theta  = v / (Jg V),   p = w kappa (Theta - 1)
    R_ai   = sum_q w_q [ s (f_ai - I1/3 g_ai) + p J g_ai ],      s = Jg w mu J^(-2/3)
    K      = sum_q w_q [ s d_ik (dN_a . dN_b) + c_fg (g_ai f_bk + f_ai g_bk)
                         + c_gg g_ai g_bk + c_swap g_ak g_bi ]
             + w kappa / (Jg V) h_ai h_bk,   h_ai = sum_q w_q J g_ai

The last term is the condensed pressure (Schur complement of the P0 block);
the rest is `material.tangent_coefficients` contracted with the gradients.
Fixed dofs get identity rows and columns so that the matrix stays
symmetric.  Work is done in chunks of elements to bound the temporaries.
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

    residual: np.ndarray  # (dofs,), zero at fixed dofs
    matrix: sp.bsr_matrix | None  # consistent tangent, identity at fixed dofs
    pressure: np.ndarray  # (elements,) Cauchy hydrostatic stress p = w kappa (Theta - 1), Pa
    theta: np.ndarray  # (elements,) mean elastic volume ratio
    min_det: np.ndarray  # (elements,) smallest det F over Gauss points and corners
    energy: float
    load: float  # |internal forces| over all dofs, reactions of fixed ones included


class Assembler:
    """Assembles on a fixed pattern; `fixed` marks dofs held at zero."""

    def __init__(self, mesh: StructuredMesh, fixed: np.ndarray, chunk: int = 4096):
        self.mesh = mesh
        self.d = d = mesh.ndim
        self.ref = mesh.reference
        self.chunk = chunk
        self.edofs = mesh.element_dofs()
        self.fixed = np.asarray(fixed, bool)
        conn = mesh.connectivity
        nloc = conn.shape[1]
        # node-level pattern: one d x d block per pair of nodes sharing an element
        keys = (conn[:, :, None].astype(np.int64) * mesh.n_nodes + conn[:, None, :]).ravel()
        unique, self.block_map = np.unique(keys, return_inverse=True)
        self.block_map = self.block_map.reshape(-1, nloc, nloc).astype(np.int64)
        rows, cols = np.divmod(unique, mesh.n_nodes)
        self.indices = cols.astype(np.int32)
        self.indptr = np.searchsorted(rows, np.arange(mesh.n_nodes + 1)).astype(np.int32)
        fixed_node = self.fixed.reshape(-1, d)
        self.keep = ~fixed_node[rows][:, :, None] & ~fixed_node[cols][:, None, :]
        diag = np.flatnonzero(rows == cols)
        node, comp = np.nonzero(fixed_node)
        self.fixed_diag = (diag[node], comp)
        # constant per Gauss point: dN_a . dN_b
        self.gram = np.einsum("qaJ,qbJ->qab", self.ref.gradients, self.ref.gradients)
        self.scatter = None  # built on the first tangent

    @property
    def n_blocks(self) -> int:
        return self.indices.size

    def gradient(self, u: np.ndarray, elements: slice, corners: bool = False) -> np.ndarray:
        """F = I + grad u at the Gauss points (or the corners) of some elements: (E, Q, 3, 3)."""
        dN = self.ref.corner_gradients if corners else self.ref.gradients
        Q, nloc, d = dN.shape
        ue = u[self.edofs[elements]].reshape(-1, nloc, d).transpose(0, 2, 1)  # (E, i, a)
        H = (ue.reshape(-1, nloc) @ dN.transpose(1, 0, 2).reshape(nloc, Q * d)).reshape(-1, d, Q, d)
        F = np.zeros((H.shape[0], Q, 3, 3))
        F[..., :d, :d] = H.transpose(0, 2, 1, 3)
        F[..., [0, 1, 2], [0, 1, 2]] += 1.0
        return F

    def evaluate(self, u: np.ndarray, w: np.ndarray, growth: np.ndarray, mu: float, kappa: float,
                 tangent: bool = True) -> Evaluation:
        """Residual (and tangent) at displacement u; w and growth Jg = (1+alpha)^3 per element."""
        mesh, d, ref = self.mesh, self.d, self.ref
        E, nloc, Q = mesh.n_elements, ref.gradients.shape[1], ref.gradients.shape[0]
        V, wq, dN = ref.volume, ref.weights, ref.gradients
        forces = np.zeros((E, nloc, d))
        blocks = np.empty((E, nloc, d, nloc, d)) if tangent else None
        pressure, theta, min_det = np.empty(E), np.empty(E), np.empty(E)
        energy = 0.0
        for start in range(0, E, self.chunk):
            part = slice(start, min(start + self.chunk, E))
            F = self.gradient(u, part)
            J, G, I1 = material.invariants(F)
            min_det[part] = np.minimum(J.min(axis=1), material.determinant(self.gradient(u, part, True)).min(axis=1))
            if np.any(J <= 0):  # leave the rest undefined: the caller rejects this state
                min_det[part] = np.minimum(min_det[part], J.min(axis=1))
                continue
            we, Jg = w[part, None], growth[part, None]
            th = (J * wq).sum(axis=1) / (Jg[:, 0] * V)
            p = we[:, 0] * kappa * (th - 1.0)
            theta[part], pressure[part] = th, p
            shear = Jg * we * mu
            energy += float((material.isochoric_energy(F, shear) * wq).sum()
                            + (Jg[:, 0] * V * we[:, 0] * kappa / 2 * (th - 1.0) ** 2).sum())
            f, g = self._contract(F, dN), self._contract(G, dN)
            s, c_fg, c_gg, c_swap = material.tangent_coefficients(J, I1, shear, p[:, None])
            stress = s[..., None, None] * (f - (I1 / 3)[..., None, None] * g) + (p[:, None] * J)[..., None, None] * g
            forces[part] = np.tensordot(wq, stress, axes=([0], [1]))
            if tangent:
                blocks[part] = self._element_matrices(f, g, J, wq, s, c_fg, c_gg, c_swap,
                                                      we[:, 0] * kappa / (Jg[:, 0] * V))
        residual = np.bincount(self.edofs.ravel(), weights=forces.ravel(), minlength=mesh.n_dofs)
        load = float(np.linalg.norm(residual))
        residual[self.fixed] = 0.0
        matrix = self._matrix(blocks) if tangent and np.all(min_det > 0) else None
        return Evaluation(residual, matrix, pressure, theta, min_det, energy, load)

    def _contract(self, T: np.ndarray, dN: np.ndarray) -> np.ndarray:
        """T_iJ dN_a/dX_J at every point: (E, Q, 3, 3) x (Q, a, J) -> (E, Q, a, i)."""
        d = self.d
        out = T[:, :, None, :d, 0] * dN[None, :, :, None, 0]
        for J in range(1, d):
            out += T[:, :, None, :d, J] * dN[None, :, :, None, J]
        return out

    def _element_matrices(self, f, g, J, wq, s, c_fg, c_gg, c_swap, bulk):
        """(E, a, i, b, k) element tangents from the per-point vectors (see module docstring)."""
        E, Q, nloc, d = g.shape
        m = nloc * d
        gq, fq = g.reshape(E, Q, m), f.reshape(E, Q, m)
        gt = gq.transpose(0, 2, 1)
        # g^T (c_gg g + c_fg f) + its transpose's f part: [g f] [[c_gg, c_fg], [c_fg, 0]] [g f]^T
        half = np.matmul(gt, (wq * c_fg)[..., None] * fq)
        K = np.matmul(gt, (wq * c_gg)[..., None] * gq)
        K += half
        K += half.transpose(0, 2, 1)
        K = K.reshape(E, nloc, d, nloc, d)
        # c_swap g_ak g_bi: the same outer product with the component indices exchanged
        swap = np.matmul(gt, (wq * c_swap)[..., None] * gq).reshape(E, nloc, d, nloc, d)
        K += swap.transpose(0, 1, 4, 3, 2)
        # s d_ik (dN_a . dN_b)
        iso = ((wq * s) @ self.gram.reshape(Q, -1)).reshape(E, nloc, nloc)
        for i in range(d):
            K[:, :, i, :, i] += iso
        # condensed pressure: rank one per element
        h = np.tensordot(wq, J[..., None] * gq, axes=([0], [1]))
        K = K.reshape(E, m, m)
        K += (bulk[:, None] * h)[:, :, None] * h[:, None, :]
        return K.reshape(E, nloc, d, nloc, d)

    def _matrix(self, blocks: np.ndarray) -> sp.bsr_matrix:
        d, n = self.d, self.mesh.n_dofs
        if self.scatter is None:  # (E, a, i, b, k) -> position in the BSR data (blocks, i, k)
            i = np.arange(d)
            self.scatter = (self.block_map[:, :, None, :, None] * d * d + i[:, None, None] * d
                            + i[None, None, :]).ravel()
        data = np.bincount(self.scatter, weights=blocks.ravel(), minlength=self.n_blocks * d * d)
        data = data.reshape(self.n_blocks, d, d)
        data *= self.keep
        data[self.fixed_diag[0], self.fixed_diag[1], self.fixed_diag[1]] = 1.0
        return sp.bsr_matrix((data, self.indices, self.indptr), shape=(n, n))
