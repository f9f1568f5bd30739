"""Between a grid and the grid of twice its cells: interpolation, restriction and the Galerkin coarse operator.

The coarse grid has ceil(n/2) cells along an axis of n (an odd count's last
coarse cell reaches past the domain).  Fine node i lies on coarse node i/2
when i is even (weight 1), else halfway between i//2 and i//2 + 1 (weights
1/2): (bi/tri)linear interpolation is the product of these along the axes,
the same for every displacement component.  Rows of held fine unknowns are
zero (`free`), so a coarse correction never moves them.

Nothing is stored: each product walks the fine nodes and their (at most 2^d)
coarse parents (numba).  The Galerkin operator A_c = P^T A P is summed in the
same walk from the fine stencil's blocks, both triangles of them, into the
coarse stencil's kept half (`stencil.py`); the coarse stencil has the same
reach, since neighbouring fine nodes have parents at most one coarse node
apart.
"""
from __future__ import annotations

import numpy as np

from .stencil import grid3, inside, jit


def coarse_shape(nodes_shape: tuple[int, ...]) -> tuple[int, ...]:
    """Nodes of the coarse grid: ceil(cells/2) + 1 along each axis of `cells` = nodes - 1."""
    return tuple(n // 2 + 1 for n in nodes_shape)


def parents_used(nodes_shape: tuple[int, ...], node_of: np.ndarray) -> np.ndarray:
    """(coarse grid nodes,) bool: the coarse nodes some fine node with unknowns interpolates from."""
    used = np.zeros(int(np.prod(coarse_shape(nodes_shape))), bool)
    _mark(grid3(nodes_shape), node_of, grid3(coarse_shape(nodes_shape)), used)
    return used


@jit
def _parents(iz, iy, ix, coarse, weights, points, index):
    """The coarse parents of the fine node (iz, iy, ix): their weights, (z, y, x) points and grid indices into
    the arrays given; how many.  Along an axis fine i lies on coarse i/2 when even (weight 1), else halfway
    between i//2 and i//2 + 1."""
    wz, wy, wx = 1.0 - 0.5 * (iz % 2), 1.0 - 0.5 * (iy % 2), 1.0 - 0.5 * (ix % 2)
    count = 0
    for a in range(1 + iz % 2):
        for b in range(1 + iy % 2):
            for c in range(1 + ix % 2):
                points[count, 0], points[count, 1], points[count, 2] = iz // 2 + a, iy // 2 + b, ix // 2 + c
                index[count] = (points[count, 0] * coarse[1] + points[count, 1]) * coarse[2] + points[count, 2]
                weights[count] = wz * wy * wx
                count += 1
    return count


@jit
def _mark(shape, node_of, coarse, used):
    weights, points, index = np.empty(8), np.empty((8, 3), np.int64), np.empty(8, np.int64)
    for iz in range(shape[0]):
        for iy in range(shape[1]):
            for ix in range(shape[2]):
                if node_of[(iz * shape[1] + iy) * shape[2] + ix] < 0:
                    continue
                for p in range(_parents(iz, iy, ix, coarse, weights, points, index)):
                    used[index[p]] = True


@jit
def prolong(d, coarse_x, coarse, coarse_of, shape, node_of, free, x):
    """x += P coarse_x: fine rows with unknowns, held components (free = 0) untouched."""
    weights, points, index = np.empty(8), np.empty((8, 3), np.int64), np.empty(8, np.int64)
    for iz in range(shape[0]):
        for iy in range(shape[1]):
            for ix in range(shape[2]):
                m = node_of[(iz * shape[1] + iy) * shape[2] + ix]
                if m < 0:
                    continue
                for p in range(_parents(iz, iy, ix, coarse, weights, points, index)):
                    c = coarse_of[index[p]]
                    for i in range(d):
                        x[m * d + i] += weights[p] * free[m * d + i] * coarse_x[c * d + i]


@jit
def restrict(d, x, shape, node_of, free, coarse, coarse_of, coarse_x):
    """coarse_x += P^T x."""
    weights, points, index = np.empty(8), np.empty((8, 3), np.int64), np.empty(8, np.int64)
    for iz in range(shape[0]):
        for iy in range(shape[1]):
            for ix in range(shape[2]):
                m = node_of[(iz * shape[1] + iy) * shape[2] + ix]
                if m < 0:
                    continue
                for p in range(_parents(iz, iy, ix, coarse, weights, points, index)):
                    c = coarse_of[index[p]]
                    for i in range(d):
                        coarse_x[c * d + i] += weights[p] * free[m * d + i] * x[m * d + i]


@jit
def galerkin(blocks, shape, steps, node_of, free, coarse, coarse_blocks):
    """coarse_blocks += the kept half of P^T A P, A the fine stencil `blocks` (both its triangles).

    Each fine pair (f, g) in either order adds w_fI w_gJ A_fg to the coarse block (I, J) of every parent I of
    f and J of g; of the coarse blocks only those with J at or after I are kept (the rest are their
    transposes), so (f, g) feeds the kept (I, J) and (g, f) the kept (J, I)."""
    d = blocks.shape[2]
    nz, ny, nx = shape[0], shape[1], shape[2]
    wf, fi, wg, gi = np.empty(8), np.empty((8, 3), np.int64), np.empty(8), np.empty((8, 3), np.int64)
    index = np.empty(8, np.int64)
    block = np.empty((d, d))
    for iz in range(nz):
        for iy in range(ny):
            for ix in range(nx):
                g = (iz * ny + iy) * nx + ix
                m = node_of[g]
                if m < 0:
                    continue
                kf = _parents(iz, iy, ix, coarse, wf, fi, index)
                for h in range(steps.shape[0]):
                    jz, jy, jx = iz + steps[h, 0], iy + steps[h, 1], ix + steps[h, 2]
                    if not inside(jz, jy, jx, shape):
                        continue
                    n = node_of[(jz * ny + jy) * nx + jx]
                    if n < 0:
                        continue
                    nonzero = False
                    for i in range(d):
                        for k in range(d):
                            block[i, k] = blocks[g, h, i, k] * free[m * d + i] * free[n * d + k]
                            nonzero |= block[i, k] != 0.0
                    if not nonzero:
                        continue
                    kg = _parents(jz, jy, jx, coarse, wg, gi, index)
                    for a in range(kf):
                        first = (fi[a, 0] * coarse[1] + fi[a, 1]) * coarse[2] + fi[a, 2]
                        for b in range(kg):
                            w = wf[a] * wg[b]
                            code = ((gi[b, 0] - fi[a, 0] + 1) * 9 + (gi[b, 1] - fi[a, 1] + 1) * 3
                                    + gi[b, 2] - fi[a, 2] + 1)  # the step from I to J, 13 = none
                            if code > 13 or (code == 13 and h == 0):  # (f, g) to the kept (I, J)
                                for i in range(d):
                                    for k in range(d):
                                        coarse_blocks[first, code - 13, i, k] += w * block[i, k]
                            elif code == 13:  # I = J: (f, g) and (g, f)
                                for i in range(d):
                                    for k in range(d):
                                        coarse_blocks[first, 0, i, k] += w * (block[i, k] + block[k, i])
                            elif h:  # (g, f) to the kept (J, I)
                                second = (gi[b, 0] * coarse[1] + gi[b, 1]) * coarse[2] + gi[b, 2]
                                for i in range(d):
                                    for k in range(d):
                                        coarse_blocks[second, 13 - code, i, k] += w * block[k, i]
