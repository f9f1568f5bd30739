"""Residual and consistent tangent of the Q1/P0 growth problem, vectorised over elements.

Apart from solving: given nodal displacements and per-element data (weight
w, growth Jg), return the internal-force vector, the exact tangent as a
symmetric stencil of ndim x ndim blocks on the grid's nodes (`stencil.py`),
and per-element pressure and volume ratios.

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

Assembly uses the grid: the tangent is kept as half a stencil of blocks on
the grid's nodes (`stencil.py`: the diagonal block and the blocks to the 13
later neighbours in 3-D, 4 in 2-D; the rest are their transposes), and element
matrices are added into it one local node pair (a, b) at a time, b at or
after a, each a shifted slice of the cell grid (no index arrays, no sorting,
no second copy).  Work goes in boxes of about `Settings.chunk` cells (whole grid
planes, or rows of one plane: `StructuredMesh.boxes`) to bound the temporaries.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..parallel import SERIAL, Team
from . import material, stencil
from .mesh import Box, StructuredMesh
from .settings import DEFAULT
from .stencil import Stencil


@dataclass
class Evaluation:
    """One evaluation at a displacement: everything Newton and the output need."""

    residual: np.ndarray  # (dofs,), zero at constrained dofs
    matrix: Stencil | None  # consistent tangent, identity at constrained dofs
    pressure: np.ndarray  # (elements,) Cauchy hydrostatic stress p = w kappa (Theta - 1), Pa
    min_det: np.ndarray  # (elements,) smallest det F over Gauss points and corners
    energy: float


class Assembler:
    """Assembles on a fixed pattern; `constrained` marks dofs held at zero."""

    def __init__(self, mesh: StructuredMesh, constrained: np.ndarray, chunk: int = DEFAULT.chunk,
                 team: Team = SERIAL):
        self.mesh = mesh
        self.team = team  # the threads of the tangent's products
        self.d = d = mesh.ndim
        self.ref = ref = mesh.reference
        nloc = ref.gradients.shape[1]
        self._pattern()
        self.constrain(constrained)
        self.boxes = mesh.boxes(chunk)
        Q = ref.gradients.shape[0]
        # constant per element: w_q dN_a . dN_b (the isotropic part), w_q dN_a/dX_J (the residual)
        self.gram = np.einsum("q,qaJ,qbJ->qab", ref.weights, ref.gradients, ref.gradients).reshape(Q, -1)
        self.weighted_dN = (ref.weights[:, None, None] * ref.gradients).transpose(0, 2, 1).reshape(Q * d, nloc)
        # displacement -> gradient at the Gauss points / corners: (nloc, Q * d) each
        self.to_points = ref.gradients.transpose(1, 0, 2).reshape(nloc, -1)
        self.to_corners = ref.corner_gradients.transpose(1, 0, 2).reshape(nloc, -1)
        self.nloc = nloc
        self.corners = [tuple(int(c) for c in ca) for ca in mesh.reference.corners[:, ::-1]]  # (a, [z,] y, x)

    def _pattern(self):
        """The local node pairs (a, b) whose block is kept (b at or after a), and which node pairs an open cell
        links (the pattern of the tangent as a sparse matrix)."""
        mesh, d = self.mesh, self.d
        cells = mesh.grid.cells_shape
        corners = mesh.reference.corners[:, ::-1]  # (a, [z,] y, x)
        centre = (3**d - 1) // 2
        self.slots = centre + 1
        self.pairs = []  # (a, b, where node a sits in the cell ([z,] y, x), stencil slot of b from a)
        for a, ca in enumerate(corners):
            for b, cb in enumerate(corners):
                slot = int(np.dot(cb - ca + 1, 3 ** np.arange(d - 1, -1, -1))) - centre
                if slot >= 0:
                    self.pairs.append((a, b, tuple(int(c) for c in ca), slot))
        self.linked = np.zeros(mesh.grid.nodes_shape + (self.slots,), bool)
        for _, _, ca, slot in self.pairs:
            self.linked[tuple(slice(c, c + n) for c, n in zip(ca, cells)) + (slot,)] |= ~mesh.obstacle
        self.linked = self.linked.reshape(-1, self.slots)

    def constrain(self, constrained: np.ndarray):
        """Hold the dofs `constrained` at zero: their rows and columns become the identity's."""
        self.constrained = np.asarray(constrained, bool)

    def _on_grid(self, u: np.ndarray) -> np.ndarray:
        """u on every grid node (nodes_shape + (d,)), zero at nodes without dofs."""
        grid = np.zeros((self.mesh.grid_to_mesh_node.size, self.d))
        grid[self.mesh.nodes] = u.reshape(-1, self.d)
        return grid.reshape(self.mesh.grid.nodes_shape + (self.d,))

    def _slab(self, values: np.ndarray, box: Box) -> np.ndarray:
        """Per-element values of a box on its cells (box.shape + ..., obstacle cells zero)."""
        if values.shape[0] == math.prod(box.shape):  # no obstacle in the box: elements are its cells
            return values.reshape(box.shape + values.shape[1:])
        slab = np.zeros((math.prod(box.shape),) + values.shape[1:])
        slab[self.mesh.cells[box.part] - box.first] = values
        return slab.reshape(box.shape + values.shape[1:])

    def gradient(self, u_grid: np.ndarray, box: Box, corners: bool = False) -> np.ndarray:
        """F = I + grad u at the Gauss points (or the corners) of a box's elements: (E, Q, 3, 3); u_grid from
        `_on_grid`."""
        d = self.d
        ue = np.stack([u_grid[box.nodes(c)] for c in self.corners], axis=-1).reshape(-1, d, self.nloc)
        if ue.shape[0] != box.part.stop - box.part.start:  # obstacles: only the open cells
            ue = ue[self.mesh.cells[box.part] - box.first]
        H = ue.reshape(-1, self.nloc) @ (self.to_corners if corners else self.to_points)  # (E d, a) x (a, Q d)
        H = H.reshape(-1, d, H.shape[1] // d, d).transpose(0, 2, 1, 3)  # (E, Q, i, J)
        F = np.zeros(H.shape[:2] + (3, 3))
        F[..., :d, :d] = H
        F[..., [0, 1, 2], [0, 1, 2]] += 1.0
        return F

    def _add_to_nodes(self, grid: np.ndarray, values: np.ndarray, box: Box):
        """Add per-element nodal values (E, a, d) of a box to the grid's nodes."""
        slab = self._slab(values, box)
        for a, corner in enumerate(self.corners):
            grid[box.nodes(corner)] += slab[..., a, :]

    def evaluate(self, u: np.ndarray, w: np.ndarray, growth: np.ndarray, mu: float, kappa: float,
                 tangent: bool = True) -> Evaluation:
        """Residual (and tangent) at displacement u; w and growth Jg = (1+alpha)^3 per element."""
        mesh, d, ref = self.mesh, self.d, self.ref
        E, nloc = mesh.n_elements, self.to_points.shape[0]
        V, wq = ref.volume, ref.weights
        u_grid, forces = self._on_grid(u), np.zeros(mesh.grid.nodes_shape + (d,))
        blocks = np.zeros(mesh.grid.nodes_shape + (self.slots, d, d)) if tangent else None
        pressure, min_det = np.zeros(E), np.empty(E)
        energy = 0.0
        for box in self.boxes:
            part = box.part
            F = self.gradient(u_grid, box)
            J = material.determinant(F)
            at_corners = material.determinant(self.gradient(u_grid, box, True))
            min_det[part] = np.minimum(J.min(axis=1), at_corners.min(axis=1))
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
            self._add_to_nodes(forces, (stress.transpose(0, 2, 1, 3).reshape(n * d, -1) @ self.weighted_dN
                                        ).reshape(n, d, nloc).transpose(0, 2, 1), box)
            if tangent:
                K = self._element_matrices(Fd, Gd, J, s, c_fg, c_gg, c_swap, we * kappa / (Jg * V))
                self._scatter(blocks, K, box)
        residual = forces.reshape(-1, d)[mesh.nodes].ravel()
        residual[self.constrained] = 0.0
        matrix = self._matrix(blocks) if tangent and np.all(min_det > 0) else None
        return Evaluation(residual, matrix, pressure, min_det, energy)

    def growth_load(self, w: np.ndarray, growth: np.ndarray, kappa: float) -> float:
        """|internal forces| at u = 0, reactions included: the force scale of Newton's tolerance.

        At u = 0, F = G = I: the isochoric stress vanishes and P = p I with
        p = w kappa (1/Jg - 1), so R_ai = p sum_q w_q dN_a/dX_i per element."""
        corner_forces = self.weighted_dN.reshape(-1, self.d, self.nloc).sum(axis=0).T  # (a, i)
        p = np.zeros(self.mesh.grid.n_cells)
        p[self.mesh.cells] = w * kappa * (1.0 / growth - 1.0)
        p = p.reshape(self.mesh.grid.cells_shape + (1,))
        forces = np.zeros(self.mesh.grid.nodes_shape + (self.d,))
        for a, corner in enumerate(self.corners):
            forces[tuple(slice(c, c + n) for c, n in zip(corner, p.shape))] += p * corner_forces[a]
        return float(np.linalg.norm(forces.reshape(-1, self.d)[self.mesh.nodes]))

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

    def _scatter(self, blocks: np.ndarray, K: np.ndarray, box: Box):
        """Add the kept blocks of a box's element matrices (E, a, b, i, k) to the stencil's blocks."""
        slab = self._slab(K, box)
        for a, b, corner, slot in self.pairs:
            blocks[box.nodes(corner) + (slot,)] += slab[..., a, b, :, :]

    def _matrix(self, blocks: np.ndarray) -> Stencil:
        mesh = self.mesh
        blocks = blocks.reshape((-1,) + blocks.shape[-3:])
        held = Stencil(blocks, mesh.grid.nodes_shape, mesh.grid_to_mesh_node, mesh.nodes, self.linked, self.team)
        stencil.hold(blocks, stencil.grid3(mesh.grid.nodes_shape), held.offsets, mesh.grid_to_mesh_node,
                     self.constrained)
        return held
