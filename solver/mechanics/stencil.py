"""A symmetric operator on the nodes of a structured grid, stored as half a stencil of ndim x ndim blocks.

Q1 couples a node with the 3^ndim nodes around it (itself included), so the
tangent is a 27-point (9-point in 2-D) stencil of 3x3 (2x2) blocks.  It is
symmetric, so each node keeps only its diagonal block and the blocks to the
neighbours after it in grid order (13 of 26 in 3-D, 4 of 8 in 2-D); the block
from a later neighbour back to it is the transpose of the one kept there.
Blocks live on the grid's nodes, where the neighbours are known by their
offsets: no column indices, no row pointers.  In 3-D that is 14 x 9 numbers per
grid node, half of a block-sparse (BSR) matrix's data, and none of its indices.

Rows are numbered as the vectors they act on: `node_of` maps every grid node
to its row block (-1: a node without unknowns, e.g. inside an obstacle), so the
same layout serves the fine mesh's dofs and every coarse grid of the
multigrid.  The product runs in one compiled pass over the nodes (numba); a
BSR matrix of the same blocks is made on request for a factorisation or
pyamg (`tobsr`), on the pattern of node pairs an open cell links (`linked`).

Slots: h = 0 is the diagonal, h > 0 the neighbour at `offsets(ndim)[h]`
((z, y, x) steps, z = 0 in 2-D), in C order of the steps.
"""
from __future__ import annotations

import itertools

import numba
import numpy as np
import scipy.sparse as sp

from ..parallel import SERIAL, Team, rows

jit = numba.njit(cache=True, nogil=True)


def offsets(ndim: int) -> np.ndarray:
    """(slots, 3) grid steps (z, y, x) of the diagonal and the later neighbours, in slot order."""
    steps = [s for s in itertools.product((-1, 0, 1), repeat=ndim) if s >= (0,) * ndim]  # C order from the centre
    return np.array([(0,) * (3 - ndim) + s for s in steps], dtype=np.int64)


def grid3(nodes_shape: tuple[int, ...]) -> np.ndarray:
    """The nodes' shape as (z, y, x), 1 node along z in 2-D."""
    return np.array((1,) * (3 - len(nodes_shape)) + tuple(nodes_shape), dtype=np.int64)


class Stencil:
    """The operator: blocks (grid nodes, slots, d, d), the grid, and which grid node is which row block."""

    def __init__(self, blocks: np.ndarray, nodes_shape: tuple[int, ...], node_of: np.ndarray, nodes: np.ndarray,
                 linked: np.ndarray | None = None, team: Team = SERIAL):
        self.blocks = blocks  # (grid nodes, slots, d, d)
        self.nodes_shape = tuple(nodes_shape)
        self.node_of = node_of  # (grid nodes,) row block of each grid node, -1 without unknowns
        self.nodes = nodes  # (row blocks,) grid node of each row block
        self.linked = linked  # (grid nodes, slots) bool: the pattern of `tobsr` (None: every block kept)
        self.team = team  # the threads of its products
        self.d = blocks.shape[2]
        self.offsets = offsets(self.d)
        self.shape = (nodes.size * self.d,) * 2
        self.dtype = np.dtype(float)

    @property
    def nbytes(self) -> int:
        return self.blocks.nbytes

    def single(self) -> Stencil:
        """The same operator with its blocks rounded to single precision (half the memory; the product still
        sums in double)."""
        return Stencil(self.blocks.astype(np.float32), self.nodes_shape, self.node_of, self.nodes, self.linked,
                       self.team)

    def matvec(self, x: np.ndarray) -> np.ndarray:
        y = np.zeros(self.shape[0])
        apply(self.blocks, grid3(self.nodes_shape), self.offsets, self.node_of, np.ascontiguousarray(x, float), y,
              self.team)
        return y

    rmatvec = matvec  # symmetric

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x)
        if x.ndim == 1:
            return self.matvec(x)
        return np.column_stack([self.matvec(column) for column in x.T]) if x.shape[1] else np.zeros((self.shape[0], 0))

    def diagonal_blocks(self) -> np.ndarray:
        """(row blocks, d, d) the diagonal blocks in row order."""
        return self.blocks[self.nodes, 0]

    def tobsr(self, blocksize=None) -> sp.bsr_matrix:
        """The same operator as a BSR matrix of its d x d blocks (whatever `blocksize` asks, as scipy's own
        `tobsr` is called), both triangles, rows and columns sorted."""
        shape = grid3(self.nodes_shape)
        index = np.unravel_index(self.nodes, tuple(shape))
        rows, cols, data = [], [], []
        for h, step in enumerate(self.offsets):
            at = [i + s for i, s in zip(index, step)]
            inside = np.logical_and.reduce([(a >= 0) & (a < n) for a, n in zip(at, shape)])
            neighbour = np.full(self.nodes.size, -1)
            neighbour[inside] = self.node_of[np.ravel_multi_index(tuple(a[inside] for a in at), tuple(shape))]
            keep = neighbour >= 0
            if self.linked is not None:
                keep &= self.linked[self.nodes, h]
            row, col, block = np.flatnonzero(keep), neighbour[keep], self.blocks[self.nodes[keep], h]
            rows.append(row), cols.append(col), data.append(block)
            if h:
                rows.append(col), cols.append(row), data.append(block.transpose(0, 2, 1))
        row, col = np.concatenate(rows), np.concatenate(cols)
        order = np.lexsort((col, row))
        indptr = np.searchsorted(row[order], np.arange(self.nodes.size + 1)).astype(np.int32)
        return sp.bsr_matrix((np.concatenate(data)[order], col[order].astype(np.int32), indptr), shape=self.shape)

    def tocsr(self) -> sp.csr_matrix:
        return self.tobsr().tocsr()

    def toarray(self) -> np.ndarray:
        return self.tobsr().toarray()


def apply(blocks, shape, steps, node_of, x, y, team: Team = SERIAL):
    """y += A x (in 3-D by a kernel written out for 3x3 blocks: numba leaves the loops over components rolled).

    One pass over the nodes in grid order.  On a team the nodes are split in blocks of layers along the slowest
    axis (z in 3-D, y in 2-D): a row receives the transposed blocks of the previous layer's nodes, then those of
    its own layer's earlier nodes, then its own sum, so the last layer's transposed blocks into the next block's
    first layer are added first, apart (a pass over one layer a block), and then each block makes the rest of
    its rows in one pass: every y entry adds the same terms in the same order as in the serial pass, bit for
    bit."""
    linear = _linear(steps, shape)
    axis = 0 if shape[0] > 1 else 1
    layers = int(shape[axis])
    count = min(team.size, layers, y.size // rows.MIN_ROWS)
    kernel = _layers3 if blocks.shape[2] == 3 else _layers
    if count < 2:
        kernel(blocks, shape, steps, linear, node_of, x, y, axis, 0, layers, True, 0, layers)
        return
    bounds = [layers * p // count for p in range(count + 1)]

    def boundary(p: int) -> None:  # a block's last layer into the next block's first, before that block's rows
        if p + 1 < count:
            kernel(blocks, shape, steps, linear, node_of, x, y, axis, bounds[p + 1] - 1, bounds[p + 1], False,
                   bounds[p + 1] - 1, bounds[p + 1])

    def rest(p: int) -> None:
        if p < count:
            last = bounds[p + 1] - (1 if p + 1 < count else 0)
            kernel(blocks, shape, steps, linear, node_of, x, y, axis, bounds[p], bounds[p + 1], True, bounds[p], last)

    team.run(boundary, site="stencil")
    team.run(rest, site="stencil")


def _linear(steps, shape) -> np.ndarray:
    """The steps as differences of grid-node index."""
    return (steps[:, 0] * shape[1] + steps[:, 1]) * shape[2] + steps[:, 2]


@jit
def _layers3(blocks, shape, steps, linear, node_of, x, y, axis, first, last, own, next_first, next_last):
    """y += A x for the nodes of layers first .. last - 1 along `axis`, 3x3 blocks: their own rows and their
    transposed blocks within their layer if `own`, and their transposed blocks to the next layer for the layers
    next_first .. next_last - 1 (`apply`); each kept block and its transpose at once."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    z0, z1 = (first, last) if axis == 0 else (0, nz)
    y0_, y1_ = (first, last) if axis == 1 else (0, ny)
    for iz in range(z0, z1):
        for iy in range(y0_, y1_):
            for ix in range(nx):
                g = (iz * ny + iy) * nx + ix
                m = node_of[g]
                if m < 0:
                    continue
                x0, x1, x2 = x[3 * m], x[3 * m + 1], x[3 * m + 2]
                y0 = y1 = y2 = 0.0
                inner = (nz == 1 or iz + 1 < nz) and 0 < iy < ny - 1 and 0 < ix < nx - 1  # every neighbour there
                onward = next_first <= (iz if axis == 0 else iy) < next_last  # its blocks to the next layer too
                for h in range(steps.shape[0]):
                    later = steps[h, axis] == 1
                    if not own and not later or later and not own and not onward:
                        continue
                    if not inner and not inside(iz + steps[h, 0], iy + steps[h, 1], ix + steps[h, 2], shape):
                        continue
                    n = node_of[g + linear[h]]
                    if n < 0:
                        continue
                    b00, b01, b02 = blocks[g, h, 0, 0], blocks[g, h, 0, 1], blocks[g, h, 0, 2]
                    b10, b11, b12 = blocks[g, h, 1, 0], blocks[g, h, 1, 1], blocks[g, h, 1, 2]
                    b20, b21, b22 = blocks[g, h, 2, 0], blocks[g, h, 2, 1], blocks[g, h, 2, 2]
                    if own:
                        v0, v1, v2 = x[3 * n], x[3 * n + 1], x[3 * n + 2]
                        y0 += b00 * v0 + b01 * v1 + b02 * v2
                        y1 += b10 * v0 + b11 * v1 + b12 * v2
                        y2 += b20 * v0 + b21 * v1 + b22 * v2
                    if h and (onward if later else own):
                        y[3 * n] += b00 * x0 + b10 * x1 + b20 * x2
                        y[3 * n + 1] += b01 * x0 + b11 * x1 + b21 * x2
                        y[3 * n + 2] += b02 * x0 + b12 * x1 + b22 * x2
                if own:
                    y[3 * m] += y0
                    y[3 * m + 1] += y1
                    y[3 * m + 2] += y2


@jit
def _layers(blocks, shape, steps, linear, node_of, x, y, axis, first, last, own, next_first, next_last):
    """`_layers3` for blocks of any size (the diagonal block and each kept block with its transpose)."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    d = blocks.shape[2]
    z0, z1 = (first, last) if axis == 0 else (0, nz)
    y0_, y1_ = (first, last) if axis == 1 else (0, ny)
    for iz in range(z0, z1):
        for iy in range(y0_, y1_):
            for ix in range(nx):
                g = (iz * ny + iy) * nx + ix
                m = node_of[g]
                if m < 0:
                    continue
                inner = (nz == 1 or iz + 1 < nz) and 0 < iy < ny - 1 and 0 < ix < nx - 1  # every neighbour there
                onward = next_first <= (iz if axis == 0 else iy) < next_last  # its blocks to the next layer too
                for h in range(steps.shape[0]):
                    later = steps[h, axis] == 1
                    if not own and not later or later and not own and not onward:
                        continue
                    if not inner and not inside(iz + steps[h, 0], iy + steps[h, 1], ix + steps[h, 2], shape):
                        continue
                    n = node_of[g + linear[h]]
                    if n < 0:
                        continue
                    if own:
                        for i in range(d):
                            total = 0.0
                            for k in range(d):
                                total += blocks[g, h, i, k] * x[n * d + k]
                            y[m * d + i] += total
                    if h and (onward if later else own):
                        for k in range(d):
                            total = 0.0
                            for i in range(d):
                                total += blocks[g, h, i, k] * x[m * d + i]
                            y[n * d + k] += total


@jit
def inside(iz, iy, ix, shape):
    return 0 <= iz < shape[0] and 0 <= iy < shape[1] and 0 <= ix < shape[2]


@jit
def hold(blocks, shape, steps, node_of, held):
    """Rows and columns of the held unknowns (`held`, per row) zeroed, their diagonal 1: they stay zero."""
    nz, ny, nx = shape[0], shape[1], shape[2]
    d = blocks.shape[2]
    for iz in range(nz):
        for iy in range(ny):
            for ix in range(nx):
                g = (iz * ny + iy) * nx + ix
                m = node_of[g]
                if m < 0:
                    continue
                for h in range(steps.shape[0]):
                    jz, jy, jx = iz + steps[h, 0], iy + steps[h, 1], ix + steps[h, 2]
                    if not inside(jz, jy, jx, shape):
                        continue
                    n = node_of[(jz * ny + jy) * nx + jx]
                    if n < 0:
                        continue
                    for i in range(d):
                        for k in range(d):
                            if held[m * d + i] or held[n * d + k]:
                                blocks[g, h, i, k] = 0.0
                for i in range(d):
                    if held[m * d + i]:
                        blocks[g, 0, i, i] = 1.0
