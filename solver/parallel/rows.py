"""Work split into blocks of rows: sparse products and vector updates on a `Team`, each entry as serial code.

A CSR product computes row i as scipy's ``csr_matvec`` does, ``sum = 0; sum += a_ij x_j`` over the row's
entries in their stored order, and stores it (or b_i - sum, or x_i + sum): no entry depends on which thread
computes it or on where the blocks end, so the result is the serial one bit for bit for any thread count
(tests/test_parallel.py).  Indices are read as unsigned (numba otherwise checks every index for wrapping
round from the end, which made its loop slower than scipy's).

Rows are split into as many contiguous blocks as the team has threads, each of at least `MIN_ROWS` rows:
below that a thread's share costs less than handing it over (~15 µs), and the calling thread does it alone.
A product counts its matrix's entries instead where they are more, `STENCIL` to a row: the multigrid's
restriction (5 315 rows of 28 entries each at 40^3) and its first coarse operator (31 a row) are products
of few rows and much work.
"""
from __future__ import annotations

from typing import Callable

import numba
import numpy as np
import scipy.sparse as sp

from .team import Team, kind

MIN_ROWS = 8192  # rows per block below which a product is not split: handing a block over costs ~15 µs
STENCIL = 7  # entries per row of the grid's 7-point matrices, on which MIN_ROWS was measured
jit = numba.njit(cache=True, nogil=True)


def blocks(n: int, team: Team, entries: int = 0) -> np.ndarray:
    """Boundaries of at most team.size contiguous blocks of range(n), each of at least `MIN_ROWS` rows, or of
    `entries` / `STENCIL` if that is more (one block if n is smaller): block p is range(bounds[p], bounds[p + 1])."""
    count = max(1, min(team.size, max(n, entries // STENCIL) // MIN_ROWS, n))
    return np.array([n * p // count for p in range(count + 1)], dtype=np.int64)


def split(team: Team, n: int, work: Callable[[int, int], None], entries: int = 0) -> None:
    """work(start, stop) over blocks of range(n), on the team's threads when n (or `entries`, those of a matrix
    whose rows these are) is large enough."""
    if team.size == 1 or max(n, entries // STENCIL) < 2 * MIN_ROWS:  # one block, without making its bounds
        work(0, n)
        return
    bounds = blocks(n, team, entries)
    if bounds.size == 2:
        work(0, n)
        return

    def part(p: int) -> None:
        if p + 1 < bounds.size:
            work(int(bounds[p]), int(bounds[p + 1]))

    team.run(part, site=kind(work))


def split_each(team: Team, sizes: list[int], work: Callable[[int, int, int], None]) -> None:
    """work(k, start, stop) over blocks of range(sizes[k]) for every k (the faces of each axis), in one call of
    the team: thread p takes block p of every k (one hand-over instead of one per k)."""
    if team.size == 1 or max(sizes, default=0) < 2 * MIN_ROWS:
        for k, n in enumerate(sizes):
            work(k, 0, n)
        return
    bounds = [blocks(n, team) for n in sizes]

    def part(p: int) -> None:
        for k, edges in enumerate(bounds):
            if p + 1 < edges.size:
                work(k, int(edges[p]), int(edges[p + 1]))

    team.run(part, site=kind(work))


CSR = (sp.csr_matrix, sp.csr_array)


def compiled(matrix) -> bool:
    """Whether the products here take `matrix` (float64 CSR); anything else is left to its own `@`.  Asked at
    every product (thousands a second in a small run): a type test, not `sp.issparse` and the `format` property."""
    return isinstance(matrix, CSR) and matrix.data.dtype == np.float64


def product(team: Team, matrix: sp.csr_matrix, x: np.ndarray) -> np.ndarray:
    """matrix @ x (float64 CSR and vector), rows in blocks on the team."""
    if not compiled(matrix):
        return matrix @ x
    y = np.empty(matrix.shape[0])
    x = np.ascontiguousarray(x, dtype=float)
    indptr, indices, data = matrix.indptr, matrix.indices, matrix.data
    split(team, y.size, lambda a, b: _product(indptr, indices, data, x, y, a, b), matrix.nnz)
    return y


def residual(team: Team, matrix: sp.csr_matrix, x: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """rhs - matrix @ x, each row as numpy computes it from scipy's product."""
    if not compiled(matrix):
        return rhs - matrix @ x
    r = np.empty(matrix.shape[0])
    x = np.ascontiguousarray(x, dtype=float)
    indptr, indices, data = matrix.indptr, matrix.indices, matrix.data
    split(team, r.size, lambda a, b: _residual(indptr, indices, data, x, rhs, r, a, b), matrix.nnz)
    return r


def add_product(team: Team, matrix: sp.csr_matrix, e: np.ndarray, x: np.ndarray) -> None:
    """x += matrix @ e in place, each row as numpy adds scipy's product."""
    if not compiled(matrix):
        x += matrix @ e
        return
    e = np.ascontiguousarray(e, dtype=float)
    indptr, indices, data = matrix.indptr, matrix.indices, matrix.data
    split(team, x.size, lambda a, b: _add_product(indptr, indices, data, e, x, a, b), matrix.nnz)


@jit
def _row(indptr, indices, data, x, i):
    total = 0.0
    for k in range(np.uint64(indptr[i]), np.uint64(indptr[i + 1])):
        total += data[k] * x[np.uint64(indices[k])]
    return total


@jit
def _product(indptr, indices, data, x, y, start, stop):
    for i in range(start, stop):
        y[i] = _row(indptr, indices, data, x, i)


@jit
def _residual(indptr, indices, data, x, rhs, r, start, stop):
    for i in range(start, stop):
        r[i] = rhs[i] - _row(indptr, indices, data, x, i)


@jit
def _add_product(indptr, indices, data, e, x, start, stop):
    for i in range(start, stop):
        x[i] = x[i] + _row(indptr, indices, data, e, i)


@jit
def with_diagonal(data, base, positions, diagonal, start, stop):
    """Rows start .. stop - 1 of a CSR matrix's data: its diagonal (at `positions`) base + `diagonal`."""
    for i in range(start, stop):
        data[positions[i]] = base[i] + diagonal[i]
