"""Compiled loops (numba) of the per-step work whose numpy form was dominated by temporaries.

Each kernel does what a few dozen whole-array numpy operations did, in one
pass over the faces or cells; the arithmetic is the same, operation by
operation, so the advection data and the pointwise velocity are those of the
numpy form bit for bit (tests/test_kernels.py) and the front's vectors agree to
round-off (measured: 4e-15 in velocities of 40 µm/T*; numpy summed the three
components of a norm and a dot product in its own order).  Compiled on first
use and cached beside this file (`cache=True`): a run after the first pays
the loading only (~0.3 s, once per process).

A kernel returns at most one array (results go into arrays passed in): numba
boxes a returned tuple through a Python function, where a signal handler's
exception (Ctrl-C, the CLI's SIGTERM) surfaced as a SystemError instead of
unwinding the run.
"""
from __future__ import annotations

import numba
import numpy as np

from .assembly import face_coefficients

jit = numba.njit(cache=True, nogil=True)


@jit
def advection_into(out: np.ndarray, faces: np.ndarray, offsets: np.ndarray, indptr: np.ndarray, w: np.ndarray,
                   phi: np.ndarray, h: float, tvd: bool, first: int = 0, last: int = -1, row_start: int = 0,
                   row_stop: int = -1) -> None:
    """Add the advection operator's CSR data (biofilm.py, positive-coefficient form) for one axis to `out`.

    faces: (4, m) lower, upper, lower_out, upper_out (-1: none); offsets: (6, m) where in their rows (from
    the row's start, `indptr`) the entries (lower, lower), (upper, upper), (upper, lower), (lower, upper),
    (lower, lower_out), (upper, upper_out) are stored (`position`).
    Entries are added in the order of the numpy form (inflow diagonal, inflow off-diagonal, outflow
    diagonal, outflow off-diagonal, each over all faces), so that the sums round alike.

    Optionally a block: only the faces first .. last - 1 (all: -1), and of their entries only those of rows
    row_start .. row_stop - 1 (all: -1); an entry's sum sees the same terms in the same order as when every face is
    done at once.  (The phi step's matrix is made row by row instead, to the same bits: `assembly.py`.)"""
    last = w.size if last < 0 else last
    row_stop = phi.size if row_stop < 0 else row_stop
    m = last - first
    inflow, outflow, forward = np.empty(m), np.empty(m), np.empty(m, np.bool_)
    face_coefficients(inflow, outflow, forward, -first, faces, w, phi, h, tvd, first, last)
    # row `down` gets inflow * (phi_down - phi_up), row `up` outflow * (phi_up - phi_far): all of one kind of entry
    # over the faces before the next kind, as the numpy form added them
    _add(out, faces, offsets, indptr, w, inflow, 1.0, 1, 1, 0, first, row_start, row_stop)
    _add(out, faces, offsets, indptr, w, inflow, -1.0, 1, 2, 3, first, row_start, row_stop)
    if tvd:
        _add(out, faces, offsets, indptr, w, outflow, 1.0, 0, 0, 1, first, row_start, row_stop)
        _add(out, faces, offsets, indptr, w, outflow, -1.0, 0, 4, 5, first, row_start, row_stop)


@jit
def _add(out, faces, offsets, indptr, w, values, sign, row, forward, backward, first, row_start, row_stop):
    """out += sign * values[k] at face first + k's entry `forward` (w > 0) or `backward` (its mirror), for the faces
    whose row (cell `row` of the face, 0 lower, 1 upper, mirrored likewise) is one of row_start .. row_stop - 1."""
    for k in range(values.size):
        f = first + k
        if row_start <= faces[row if w[f] > 0 else 1 - row, f] < row_stop:
            if sign > 0:
                out[position(faces, offsets, indptr, forward if w[f] > 0 else backward, f)] += values[k]
            else:
                out[position(faces, offsets, indptr, forward if w[f] > 0 else backward, f)] -= values[k]


ROWS = np.array([0, 1, 1, 0, 0, 1])  # the row (lower 0, upper 1) of each of a face's six entries (`advection_into`)


@jit
def position(faces: np.ndarray, offsets: np.ndarray, indptr: np.ndarray, entry: int, f: int) -> int:
    """Where face f's entry `entry` (0 .. 5, `advection_into`) is in the CSR data: its row's start and offset."""
    return indptr[faces[ROWS[entry], f]] + offsets[entry, f]


@jit
def row_offsets(indptr: np.ndarray, indices: np.ndarray, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """For each (rows[k], columns[k]) the offset of its entry from its row's start in a CSR pattern (rows of at most
    255 entries); -1 for an entry the pattern does not have."""
    found = np.full(rows.size, -1, np.int64)
    for k in range(rows.size):
        start = indptr[rows[k]]
        for j in range(start, indptr[rows[k] + 1]):
            if indices[j] == columns[k]:
                found[k] = j - start
                break
    return found


@jit
def face_gradient(normal: np.ndarray, magnitude: np.ndarray, c: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  axis: int, cell_gradient: np.ndarray, h: float, start: int, stop: int) -> None:
    """Per face start .. stop - 1 of one axis, into `normal` and `magnitude`: the normal derivative
    (c_upper - c_lower)/h and |grad c| with the tangential components from the mean of the two cells' central
    differences (`cell_gradient`: (ndim, n))."""
    for f in range(start, stop):
        a, b = lower[f], upper[f]
        dn = (c[b] - c[a]) / h
        squared = dn * dn
        for k in range(cell_gradient.shape[0]):
            if k != axis:
                t = 0.5 * (cell_gradient[k, a] + cell_gradient[k, b])
                squared += t * t
        normal[f] = dn
        magnitude[f] = np.sqrt(squared)


@jit
def face_velocity(w: np.ndarray, c: np.ndarray, lower: np.ndarray, upper: np.ndarray, normal: np.ndarray,
                  magnitude: np.ndarray, r: float, k: float, floor: float, start: int, stop: int) -> None:
    """Into w, per face start .. stop - 1: r c_f/(k + c_f) (dc/dn) / max(|grad c|, floor), c_f the mean of the two
    cells."""
    for f in range(start, stop):
        cf = 0.5 * (c[lower[f]] + c[upper[f]])
        w[f] = r * cf / (k + cf) * normal[f] / max(magnitude[f], floor)


@jit
def front_crossings(sums: np.ndarray, count: np.ndarray, lower: np.ndarray, upper: np.ndarray, axis: int,
                    c: np.ndarray, phi: np.ndarray, grad_c: np.ndarray, grad_phi: np.ndarray, level: float,
                    h: float, r: float, k: float, floor: float, first: int, last: int, row_start: int,
                    row_stop: int) -> None:
    """For every face of one axis that the phi = `level` front crosses: the vector F N at the crossing
    (front.py, step 1), added to `sums` (n, ndim) of the crossing's nearer cell, and that cell's `count`.

    grad_c, grad_phi: (ndim, n) cell gradients; F N is interpolated linearly between the two cells, with
    the face-normal component of grad phi from the two cells.  A team's block: faces first .. last - 1, and
    of them only those whose nearer cell is one of rows row_start .. row_stop - 1 (each cell's sums add the
    same terms in the same order as when every face is done at once)."""
    ndim = grad_c.shape[0]
    g_phi = np.empty(ndim)
    g_c = np.empty(ndim)
    for f in range(first, last):
        a, b = lower[f], upper[f]
        if (phi[a] >= level) == (phi[b] >= level):
            continue
        theta = (phi[a] - level) / (phi[a] - phi[b])  # 0 at a, 1 at b
        c_x = (1 - theta) * c[a] + theta * c[b]
        for i in range(ndim):
            g_c[i] = (1 - theta) * grad_c[i, a] + theta * grad_c[i, b]
            g_phi[i] = (1 - theta) * grad_phi[i, a] + theta * grad_phi[i, b]
        g_phi[axis] = (phi[b] - phi[a]) / h
        norm_phi, norm_c = 0.0, 0.0
        for i in range(ndim):
            norm_phi += g_phi[i] * g_phi[i]
            norm_c += g_c[i] * g_c[i]
        norm_phi, norm_c = np.sqrt(norm_phi), max(np.sqrt(norm_c), floor)
        along = 0.0
        for i in range(ndim):
            along += (-g_phi[i] / norm_phi) * (g_c[i] / norm_c)
        owner = a if theta < 0.5 else b
        if not row_start <= owner < row_stop:
            continue
        speed = r * c_x / (k + c_x) * along
        for i in range(ndim):
            sums[owner, i] += speed * (-g_phi[i] / norm_phi)
        count[owner] += 1


@jit
def extended_faces(out: np.ndarray, w: np.ndarray, lower: np.ndarray, upper: np.ndarray, axis: int,
                   nearest: np.ndarray, vectors: np.ndarray, start: int, stop: int) -> None:
    """Into out, face velocities of one axis (faces start .. stop - 1): the mean of the two cells' extended
    vectors' `axis` components (a cell's vector: row nearest[cell] of `vectors`) where both cells are covered by
    the extension (nearest >= 0), the one covered cell's where only one is, else `w`."""
    for f in range(start, stop):
        a, b = nearest[lower[f]], nearest[upper[f]]
        va = vectors[a, axis] if a >= 0 else 0.0
        vb = vectors[b, axis] if b >= 0 else 0.0
        out[f] = 0.5 * (va + vb) if a >= 0 and b >= 0 else (va + vb if a >= 0 or b >= 0 else w[f])


@jit
def nearest_rows(n: int, front: np.ndarray, candidates: np.ndarray, dense: np.ndarray, distance: np.ndarray,
                 source: np.ndarray, band: float) -> np.ndarray:
    """Per cell the row in `front` of the front cell Dijkstra found nearest (`source`, `distance` per candidate,
    local indices), for candidates on the dense side or within `band` of it; -1 elsewhere."""
    row = np.full(n, -1, np.int64)
    for i in range(front.size):
        row[front[i]] = i
    nearest = np.full(n, -1, np.int64)
    for i in range(candidates.size):
        if source[i] >= 0 and (dense[candidates[i]] or distance[i] <= band):
            nearest[candidates[i]] = row[candidates[source[i]]]
    return nearest


@jit
def subgraph(indptr: np.ndarray, indices: np.ndarray, keep: np.ndarray, local: np.ndarray,
             new_indices: np.ndarray) -> np.ndarray:
    """The pattern of graph[keep][:, keep] for a graph's CSR pattern without its diagonal (rows and columns of the kept
    vertices, in their order; `local` maps a kept vertex to its new index), the same as scipy's fancy indexing:
    returns its indptr and fills the first indptr[-1] entries of `new_indices` (at least as long as `indices`)."""
    rows = np.flatnonzero(keep)
    new_indptr = np.zeros(rows.size + 1, np.int32)
    out = 0
    for i in range(rows.size):
        row = rows[i]
        for j in range(indptr[row], indptr[row + 1]):
            if keep[indices[j]] and indices[j] != row:
                new_indices[out] = local[indices[j]]
                out += 1
        new_indptr[i + 1] = out
    return new_indptr


@jit
def central_differences(out: np.ndarray, q: np.ndarray, below: np.ndarray, above: np.ndarray, h2: float,
                        start: int, stop: int) -> None:
    """Into out (ndim, n): per axis (q[above] - q[below]) / h2 for cells start .. stop - 1 (`below`, `above`:
    (ndim, n) neighbours)."""
    for k in range(below.shape[0]):
        for i in range(start, stop):
            out[k, i] = (q[above[k, i]] - q[below[k, i]]) / h2


@jit
def within_reach(start: np.ndarray, shape: np.ndarray, reach: int) -> np.ndarray:
    """Cells of a grid (C order, `shape` (nz, ny, nx) or (ny, nx)) within `reach` face steps of a `start` cell,
    through every cell of the grid: scipy.ndimage's binary dilation with the cross structure, `reach` times."""
    total = 1
    for s in shape:
        total *= s
    steps = np.full(total, -1, np.int64)
    strides = np.ones(shape.size, np.int64)
    for k in range(shape.size - 2, -1, -1):
        strides[k] = strides[k + 1] * shape[k + 1]
    queue = np.empty(total, np.int64)
    head, tail = 0, 0
    for cell in start:
        if steps[cell] < 0:
            steps[cell] = 0
            queue[tail] = cell
            tail += 1
    while head < tail:
        cell = queue[head]
        head += 1
        if steps[cell] == reach:
            continue
        for k in range(shape.size):
            position = (cell // strides[k]) % shape[k]
            for move in (-1, 1):
                if 0 <= position + move < shape[k]:
                    other = cell + move * strides[k]
                    if steps[other] < 0:
                        steps[other] = steps[cell] + 1
                        queue[tail] = other
                        tail += 1
    return steps >= 0


@jit
def biofilm_sources(rhs: np.ndarray, phi: np.ndarray, alpha: np.ndarray, k_alpha: float, dt: float, start: int,
                    stop: int) -> float:
    """rhs = max(phi / dt + k_alpha alpha, 0) for cells start .. stop - 1 (a sink, alpha < 0 in Table 1's expansion,
    takes at most what is there; NaN kept, as by np.maximum); returns the largest phi + dt k_alpha alpha among them
    (NaN if one is), at least 0: the maximum principle's bound of the step."""
    largest = 0.0
    for i in range(start, stop):
        source = k_alpha * alpha[i]
        value = phi[i] / dt + source
        rhs[i] = value if value >= 0.0 or value != value else 0.0
        bound = phi[i] + dt * source
        if largest == largest and (bound > largest or bound != bound):  # a NaN is kept, as by np.max
            largest = bound
    return largest


@jit
def add_inflow(rate: np.ndarray, scratch: np.ndarray, lower: np.ndarray, upper: np.ndarray, w: np.ndarray) -> None:
    """rate += per cell the sum of |w_f| over the faces of one axis that flow into it (w_f > 0: into `upper`, else
    into `lower`), that sum made in `scratch` first, face by face in order from 0 (numpy's bincount, added as
    a whole to rate)."""
    for i in range(scratch.size):
        scratch[i] = 0.0
    for f in range(w.size):
        if w[f] > 0:
            scratch[upper[f]] += abs(w[f])
        else:
            scratch[lower[f]] += abs(w[f])
    for i in range(rate.size):
        rate[i] = rate[i] + scratch[i]


@jit
def largest_quotient(values: np.ndarray, h: float) -> float:
    """max(0, max_i values[i] / h), NaN if a quotient is (np.max(values / h, initial=0.0))."""
    largest = 0.0
    for i in range(values.size):
        q = values[i] / h
        if q != q:
            return q
        if q > largest:
            largest = q
    return largest
