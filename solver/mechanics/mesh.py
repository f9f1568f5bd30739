"""The transport grid as a Q1 finite-element mesh: cells are elements, grid nodes are nodes.

Every open (non-obstacle) cell is one trilinear hexahedron (bilinear
quadrilateral in 2-D); obstacle cells get no element.  All elements are the
same cube of edge h, so the basis gradients at the quadrature points are the
same for every element: they are taken once from scikit-fem (`ElementHex1` /
`ElementQuad1`, 2x2(x2) Gauss points, exact for the Q1 mass and enough for
the stiffness) on a one-element mesh and reused for all of them.

Numbering: element e is the cell with FiPy index e (x fastest); node n is the
grid node with C-order index in ``grid.nodes_shape``; only nodes that touch
an open cell carry degrees of freedom, numbered node-major,
dof = active_node * ndim + component (x, y[, z]).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from skfem import CellBasis, ElementHex1, ElementQuad1, MeshHex, MeshQuad

from ..problem import Grid


@dataclass(frozen=True)
class ReferenceElement:
    """Q1 on one cube of edge h: gradients dN[q, a, J], weights dx[q], corner offsets[a] (in cells, x first)."""

    gradients: np.ndarray
    weights: np.ndarray
    corners: np.ndarray
    corner_gradients: np.ndarray  # dN at the element's own corners, for the det F > 0 check

    @property
    def volume(self) -> float:
        return float(self.weights.sum())


def reference_element(ndim: int, h: float) -> ReferenceElement:
    """Basis gradients and weights of scikit-fem's Q1 element on the cube [0, h]^ndim."""
    edge = np.array([0.0, h])
    mesh = MeshHex.init_tensor(edge, edge, edge) if ndim == 3 else MeshQuad.init_tensor(edge, edge)
    element = ElementHex1() if ndim == 3 else ElementQuad1()
    gauss = CellBasis(mesh, element, intorder=2)
    corners = mesh.p[:, mesh.t[:, 0]] / h  # basis function a belongs to the corner at these cell offsets
    # element.doflocs are the reference points of the local nodes: evaluating there gives the
    # gradients at corner a in the same order (the reference-to-cell map is not the identity)
    at_corners = CellBasis(mesh, element, quadrature=(element.doflocs.T, np.ones(len(element.doflocs))))

    def grads(basis):
        # basis.basis[a][0].grad has shape (ndim, elements=1, points): -> [point, a, J]
        return np.stack([phi[0].grad[:, 0, :].T for phi in basis.basis], axis=1)

    return ReferenceElement(
        gradients=grads(gauss), weights=gauss.dx[0].copy(),
        corners=np.rint(corners.T).astype(int), corner_gradients=grads(at_corners),
    )


class StructuredMesh:
    """Elements, nodes and dofs of the open part of a `Grid`."""

    def __init__(self, grid: Grid, obstacle: np.ndarray | None = None):
        self.grid = grid
        self.ndim = grid.ndim
        self.h = grid.spacing
        self.obstacle = (np.zeros(grid.cells_shape, bool) if obstacle is None
                         else np.asarray(obstacle, bool).reshape(grid.cells_shape))
        self.reference = reference_element(self.ndim, self.h)

        cells = np.indices(grid.cells_shape).reshape(self.ndim, -1).T  # (cells, [z,] y, x)
        self.cells = np.flatnonzero(~self.obstacle.ravel())  # FiPy index of each element
        offsets = self.reference.corners[:, ::-1]  # (a, [z,] y, x)
        corner_index = cells[self.cells][:, None, :] + offsets[None, :, :]
        grid_nodes = np.ravel_multi_index(tuple(np.moveaxis(corner_index, -1, 0)), grid.nodes_shape)

        used = np.zeros(int(np.prod(grid.nodes_shape)), bool)
        used[grid_nodes.ravel()] = True
        self.nodes = np.flatnonzero(used)  # grid node index of each mesh node
        renumber = np.full(used.size, -1)
        renumber[self.nodes] = np.arange(self.nodes.size)
        self.connectivity = renumber[grid_nodes]  # (elements, corners) -> mesh node
        self.grid_to_mesh_node = renumber

    @property
    def n_elements(self) -> int:
        return self.cells.size

    @property
    def n_nodes(self) -> int:
        return self.nodes.size

    @property
    def n_dofs(self) -> int:
        return self.n_nodes * self.ndim

    def node_coordinates(self) -> np.ndarray:
        """(mesh nodes, ndim) positions in µm, components x, y[, z]."""
        index = np.unravel_index(self.nodes, self.grid.nodes_shape)  # ([z,] y, x)
        return np.stack(index[::-1], axis=1) * self.h

    def node_grid_index(self) -> tuple[np.ndarray, ...]:
        """Grid-node multi-index ([z,] y, x) of each mesh node."""
        return np.unravel_index(self.nodes, self.grid.nodes_shape)

    def boxes(self, chunk: int) -> list[Box]:
        """The grid's cells in boxes of about `chunk` cells, assembled one at a time to bound the temporaries:
        whole grid planes, or in 3-D, where a plane has more than `chunk` cells, rows of one plane.  Boxes
        without an open cell are left out."""
        cells = self.grid.cells_shape
        plane = math.prod(cells[1:])
        if plane <= chunk or self.ndim < 3:
            step = max(1, chunk // plane)
            leads = [(slice(z, min(z + step, cells[0])),) for z in range(0, cells[0], step)]
        else:
            rows = max(1, chunk // cells[2])
            leads = [(slice(z, z + 1), slice(y, min(y + rows, cells[1])))
                     for z in range(cells[0]) for y in range(0, cells[1], rows)]
        found = []
        for lead in leads:
            at = lead + tuple(slice(0, n) for n in cells[len(lead):])
            first = int(np.ravel_multi_index(tuple(s.start for s in at), cells))
            part = slice(*(int(i) for i in np.searchsorted(self.cells, [first, first + math.prod(
                s.stop - s.start for s in at)])))
            if part.start < part.stop:
                found.append(Box(at, part, first))
        return found


@dataclass(frozen=True)
class Box:
    """A block of cells: whole grid planes or rows of one plane, so its cells, and its elements (the open cells,
    numbered in grid order), are consecutive."""

    at: tuple[slice, ...]  # the cells, per axis ([z,] y, x)
    part: slice  # its elements
    first: int  # grid index of its first cell

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(s.stop - s.start for s in self.at)

    def nodes(self, corner) -> tuple[slice, ...]:
        """The grid nodes at `corner` (offsets in cells, ([z,] y, x)) of each of its cells."""
        return tuple(slice(s.start + c, s.stop + c) for s, c in zip(self.at, corner))
