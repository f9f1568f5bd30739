"""Work split into blocks of rows: sparse products and vector updates on a `Team`, each entry as serial code.

A CSR product computes row i as scipy's ``csr_matvec`` does, ``sum = 0; sum += a_ij x_j`` over the row's
entries in their stored order, and stores it (or b_i - sum, or x_i + sum): no entry depends on which thread
computes it or on where the blocks end, so the result is the serial one bit for bit for any thread count
(tests/test_parallel.py).  Indices are read as unsigned (numba otherwise checks every index for wrapping
round from the end, which made its loop slower than scipy's).

Rows are split into as many contiguous blocks as the team has threads, each of at least `MIN_ROWS` rows:
below that a thread's share costs less than handing it over (~15 µs), and the calling thread does it alone.
"""
from __future__ import annotations

from typing import Callable

import numba
import numpy as np
import scipy.sparse as sp

from .team import Team, kind

MIN_ROWS = 8192  # rows per block below which a product is not split: handing a block over costs ~15 µs
jit = numba.njit(cache=True, nogil=True)


def blocks(n: int, team: Team) -> np.ndarray:
    """Boundaries of at most team.size contiguous blocks of range(n), each of at least `MIN_ROWS` rows (one block
    if n is smaller): block p is range(bounds[p], bounds[p + 1])."""
    count = max(1, min(team.size, n // MIN_ROWS))
    return np.array([n * p // count for p in range(count + 1)], dtype=np.int64)


def split(team: Team, n: int, work: Callable[[int, int], None]) -> None:
    """work(start, stop) over blocks of range(n), on the team's threads when n is large enough."""
    if team.size == 1 or n < 2 * MIN_ROWS:  # one block (`blocks`), without making its bounds: most calls of a small run
        work(0, n)
        return
    bounds = blocks(n, team)
    if bounds.size == 2:
        work(0, n)
        return

    def part(p: int) -> None:
        if p + 1 < bounds.size:
            work(int(bounds[p]), int(bounds[p + 1]))

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
    split(team, y.size, lambda a, b: _product(indptr, indices, data, x, y, a, b))
    return y


def residual(team: Team, matrix: sp.csr_matrix, x: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """rhs - matrix @ x, each row as numpy computes it from scipy's product."""
    if not compiled(matrix):
        return rhs - matrix @ x
    r = np.empty(matrix.shape[0])
    x = np.ascontiguousarray(x, dtype=float)
    indptr, indices, data = matrix.indptr, matrix.indices, matrix.data
    split(team, r.size, lambda a, b: _residual(indptr, indices, data, x, rhs, r, a, b))
    return r


def add_product(team: Team, matrix: sp.csr_matrix, e: np.ndarray, x: np.ndarray) -> None:
    """x += matrix @ e in place, each row as numpy adds scipy's product."""
    if not compiled(matrix):
        x += matrix @ e
        return
    e = np.ascontiguousarray(e, dtype=float)
    indptr, indices, data = matrix.indptr, matrix.indices, matrix.data
    split(team, x.size, lambda a, b: _add_product(indptr, indices, data, e, x, a, b))


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
