"""Gauss-Seidel sweeps on several threads that give the serial sweep's result bit for bit.

A forward sweep updates x_i = (b_i - sum_{j != i} a_ij x_j) / a_ii row after row: row i reads the new x_j of
the rows before it and the old x_j of those after it.  Any order of the rows that respects those two
dependencies computes the same numbers.  On a grid numbered x fastest (the transport's cells, and the
coarse levels of its multigrid, whose rows keep the order of the fine cells they came from), the rows are
put in blocks by their layer along the slowest axis (z in 3-D, y in 2-D) and, within a layer, into as many
lanes along the next axis as there are threads; thread t sweeps lane t of layer 0, 1, 2, ... and starts a
layer once every thread before it has finished that layer and every thread after it the layer `lag` below,
`lag` the fewest layers between two coupled rows of which the one in the later layer is in the earlier lane
(`layers_ahead`).  The grid's 7- and 5-point matrices have no such pair (lag = every layer: the lanes run
side by side, 1.5 ms against pyamg's 2.8 ms at 64^3 on 2 threads); Ruge-Stueben's coarse levels couple
diagonal neighbours (lag 1: the lanes take turns, no faster than one thread, so they are swept serially).
A block then comes after every block that holds an earlier row it is coupled to, provided no stored entry
couples a row to an earlier row of a later layer or of a later lane in its own layer: `pipelined` checks
that on the matrix's pattern (true of any matrix whose couplings are between cells near each other in grid
order) and the sweep is done serially by pyamg otherwise.  The backward sweep is the mirror image.  The
threads wait for one another through atomic counters (`atomic.py`): a layer's rows (a few hundred to a few
thousand) are the unit of work between waits.

A pipeline is only as fast as its slowest thread at every layer: on a machine whose processors are busy with
other work a thread waits for one that is not running (measured: 7 times slower than one thread at load 20 on
2 cores).  Either way of sweeping gives the same numbers, so the faster is chosen as the run goes: the time of
each sweep is kept (a running mean of each way), the pipeline is used while it is the faster, and the other
way is timed again every `SAMPLE`-th sweep (the pipeline, while it is the slower: after twice as many sweeps
each time, up to `PATIENCE`).  Such a probe's time replaces its way's mean instead of joining it: blended in
with weight 0.25, one slow first pipelined sweep (9.1 ms against 2.7 ms serial at 64^3, at load 1.7) would keep
a pipeline of 1.6 ms the "slower" for some 1000 sweeps, its probes ever rarer (a 30-step run makes ~530).
"""
from __future__ import annotations

import time

import numba
import numpy as np
import scipy.sparse as sp
from pyamg.amg_core import gauss_seidel

from . import rows
from .atomic import store_release, wait_until
from .team import Team

jit = numba.njit(cache=True, nogil=True)
LINE = 8  # int64 counters per thread: one cache line each, so that a thread's counter is not its neighbour's
SAMPLE = 16  # every this many sweeps one is made the way not in use, to time it again (the pipeline: after
PATIENCE = 1024  # twice as many each time it was the slower, up to this many)
WEIGHT = 0.25  # of a new time in the running mean of a way's times


class Sweeps:
    """Forward and backward Gauss-Seidel sweeps on matrices of one pattern, pipelined over a team when the
    pattern allows it (else serial: pyamg's kernel)."""

    def __init__(self, pattern: sp.csr_matrix, layer: np.ndarray | None, lane: np.ndarray | None, team: Team,
                 adaptive: bool = True):
        self.team = team
        self.adaptive = adaptive  # choose the faster way as the run goes (False: always the pipeline)
        n = pattern.shape[0]
        self.count = min(team.size, max(1, n // rows.MIN_ROWS)) if layer is not None and lane is not None else 1
        self.pattern = (pattern.indptr, pattern.indices)
        if self.count > 1:
            lane = np.asarray(lane, np.int64)
            chunk = lane * self.count // (int(lane.max(initial=0)) + 1)
            layer = np.asarray(layer, np.int64)
            if not pipelined(pattern, layer, chunk, self.count):
                self.count = 1
        if self.count > 1:
            layers = int(layer.max(initial=0)) + 1
            key = chunk * layers + layer
            self.order = np.lexsort((np.arange(n), key)).astype(np.int32 if n < 2**31 else np.int64)  # lane, layer, row
            keys = np.arange(self.count * layers + 1, dtype=np.int64)
            self.starts = np.searchsorted(key[self.order], keys).astype(np.int64)
            self.layers = layers
            self.lag = layers_ahead(pattern, layer, chunk, layers)
            self.progress = np.zeros((self.count, LINE), np.int64)
        self.seconds = {True: 0.0, False: 0.0}  # running mean of a sweep's time, pipelined or serial (0: not yet)
        self.sweeps = 0
        self.retry = (0, SAMPLE // 2)  # while serial is the faster: the sweep that times the pipeline next, and after
        # how many sweeps it did

    def forward(self, matrix: sp.csr_matrix, x: np.ndarray, b: np.ndarray, zero: bool = False) -> None:
        """One forward sweep on x in place (rows in increasing order); `zero`: x is 0 on entry, so that a row's
        terms of the rows after it (a_ij x_j, j > i, still 0 when row i is swept) are left out (`_relax`)."""
        self._sweep(matrix, x, b, True, zero)

    def backward(self, matrix: sp.csr_matrix, x: np.ndarray, b: np.ndarray) -> None:
        """One backward sweep on x in place (rows in decreasing order)."""
        self._sweep(matrix, x, b, False)

    def _sweep(self, matrix, x, b, forward: bool, zero: bool = False) -> None:
        if self.count == 1 or not self._same_pattern(matrix) or (self.adaptive and self.lag == 1):
            self._serial(matrix, x, b, forward, zero)  # lag 1: the lanes take turns, one thread's time and the handoffs
            return
        if not self.adaptive:
            self._pipelined(matrix, x, b, forward, zero)
            return
        self.sweeps += 1
        timed = self.seconds
        slower = bool(timed[False] and timed[True] and timed[True] > timed[False])  # the pipeline, so far
        if not (timed[False] and timed[True]):  # time each way once, the pipeline first
            pipeline = not timed[True]
        elif not slower:  # the pipeline is the faster: the serial sweep timed every SAMPLE-th
            pipeline = self.sweeps % SAMPLE != 0
        else:
            pipeline = self.sweeps >= self.retry[0]
        probe = bool(timed[False] and timed[True]) and pipeline == slower  # the way not in use, timed again
        began = time.perf_counter()
        (self._pipelined if pipeline else self._serial)(matrix, x, b, forward, zero)
        seconds = time.perf_counter() - began
        fresh = probe or not timed[pipeline]  # a probe replaces its way's mean: the old one is stale, and may hold
        timed[pipeline] = seconds if fresh else (1 - WEIGHT) * timed[pipeline] + WEIGHT * seconds  # a cold start
        if pipeline and timed[False] and timed[True] > timed[False]:  # slower: try again later, later each time
            interval = min(2 * self.retry[1], PATIENCE) if slower else SAMPLE
            self.retry = (self.sweeps + interval, interval)

    @staticmethod
    def _serial(matrix, x, b, forward: bool, zero: bool = False) -> None:
        n = matrix.shape[0]
        if zero and forward:
            _lower_sweep(matrix.indptr, matrix.indices, matrix.data, x, b)
            return
        gauss_seidel(matrix.indptr, matrix.indices, matrix.data, x, b, *((0, n, 1) if forward else (n - 1, -1, -1)))

    def _pipelined(self, matrix, x, b, forward: bool, zero: bool = False) -> None:
        self.progress[:] = 0
        kernel = _forward if forward else _backward
        indptr, indices, data, order, starts, progress = (matrix.indptr, matrix.indices, matrix.data, self.order,
                                                          self.starts, self.progress)
        count, layers, lag = self.count, self.layers, self.lag

        def part(t: int) -> None:
            if t < count:
                kernel(indptr, indices, data, x, b, order, starts, layers, lag, progress, t, count, zero)

        self.team.run(part, together=True)


    def _same_pattern(self, matrix) -> bool:
        """Whether `matrix` has the pattern the pipeline was checked on (the same arrays, or equal ones: the
        last matrix found equal is remembered)."""
        indptr, indices = self.pattern
        if matrix.indices is indices and matrix.indptr is indptr:
            return True
        if np.array_equal(matrix.indptr, indptr) and np.array_equal(matrix.indices, indices):
            self.pattern = (matrix.indptr, matrix.indices)
            return True
        return False


def pipelined(pattern: sp.csr_matrix, layer: np.ndarray, chunk: np.ndarray, count: int) -> bool:
    """Whether every stored entry (i, j) couples row i to rows of blocks ordered as the rows are: for j < i the
    block (layer, lane) of j at or before i's, for j > i at or after (the pipelined sweep is then the serial
    one)."""
    row = np.repeat(np.arange(pattern.shape[0], dtype=np.int64), np.diff(pattern.indptr))
    col = pattern.indices.astype(np.int64)
    block = layer * count + chunk
    earlier = np.sign(col - row)
    later_block = np.sign(block[col] - block[row])
    return bool(np.all((later_block == 0) | (later_block == earlier)))


def layers_ahead(pattern: sp.csr_matrix, layer: np.ndarray, chunk: np.ndarray, layers: int) -> int:
    """How many layers a lane may run ahead of the lanes after it (behind them in a backward sweep): the fewest
    layers between two coupled rows of which the one in the later layer is in the earlier lane (`layers`: no such
    pair, as on the 7-point and 5-point grids, whose couplings join rows of one layer or of one lane)."""
    row = np.repeat(np.arange(pattern.shape[0], dtype=np.int64), np.diff(pattern.indptr))
    col = pattern.indices.astype(np.int64)
    across = layer[col] - layer[row]
    opposite = across * (chunk[col] - chunk[row]) < 0
    return int(np.abs(across[opposite]).min(initial=layers))


@jit
def _relax(indptr, indices, data, x, b, order, first, stop, step, zero=False):
    """pyamg's Gauss-Seidel update (amg_core/relaxation.h), operation for operation, of the rows order[first],
    order[first + step], ... before order[stop].  A block per call: with a call per row (not inlined) the sweep
    took 1.8 times pyamg's.  `zero` (a forward sweep from x = 0): the terms a_ij x_j of rows j > i are left out,
    which changes no bit: they are +-0, and a sum that starts from +0 is never -0, so adding them leaves it as it
    is."""
    for k in range(first, stop, step):
        i = order[k]
        total = 0.0
        diagonal = 0.0
        for m in range(np.uint64(indptr[i]), np.uint64(indptr[i + 1])):
            j = indices[m]
            if j == i:
                diagonal = data[m]
            elif zero and j > i:
                continue
            else:
                total += data[m] * x[np.uint64(j)]
        if diagonal != 0.0:
            x[i] = (b[i] - total) / diagonal


@jit
def _lower_sweep(indptr, indices, data, x, b):
    """A forward sweep from x = 0 in row order: `_relax` with zero, every row (the serial way)."""
    for i in range(x.size):
        total = 0.0
        diagonal = 0.0
        for m in range(np.uint64(indptr[i]), np.uint64(indptr[i + 1])):
            j = indices[m]
            if j == i:
                diagonal = data[m]
            elif j < i:
                total += data[m] * x[np.uint64(j)]
        if diagonal != 0.0:
            x[i] = (b[i] - total) / diagonal


@jit
def _forward(indptr, indices, data, x, b, order, starts, layers, lag, progress, t, count, zero=False):
    """Thread t's lane, layer by layer upward: a layer once the lanes before have done it and those after the
    layer `lag` below (`lag`: the fewest layers between coupled rows of which the later layer's is in the earlier
    lane; with 1 the lanes take turns)."""
    for g in range(layers):
        for s in range(count):
            if s < t:
                wait_until(progress, s, g + 1)
            elif s > t:
                wait_until(progress, s, g - lag + 1)
        block = t * layers + g
        _relax(indptr, indices, data, x, b, order, starts[block], starts[block + 1], 1, zero)
        store_release(progress[t], 0, g + 1)


@jit
def _backward(indptr, indices, data, x, b, order, starts, layers, lag, progress, t, count, zero=False):
    """Thread t's lane, layer by layer downward, rows in decreasing order: the mirror of `_forward`."""
    for done in range(layers):
        g = layers - 1 - done
        for s in range(count):
            if s > t:
                wait_until(progress, s, done + 1)
            elif s < t:
                wait_until(progress, s, done - lag + 1)
        block = t * layers + g
        _relax(indptr, indices, data, x, b, order, starts[block + 1] - 1, starts[block] - 1, -1)
        store_release(progress[t], 0, done + 1)
