"""The phi step's matrix made row by row: each entry written once, its terms summed as face by face.

The face-by-face form (`kernels.advection_into`, which `Biofilm.advection` keeps) adds the advection operator's
entries face by face (biofilm.py: the inflow face's a (phi_D - phi_U), TVD's outflow correction on the upwind
pair): four passes over the faces of each axis, each a read-modify-write of an entry somewhere in the matrix's
data, after a pass that cleared it; the diffusion and 1/dt were added by one more pass.  Here the faces'
coefficients are made first (one pass, the same arithmetic), and then each row gathers its own entries' terms
from its faces in the order in which those passes added them, into a sum that starts from the same 0: for a
row i and an axis, with fb the face below i and fa the one above (fb comes first in face order),

    diagonal:           + inflow of fb if it flows into i, + that of fa; then (TVD) + outflow of fb if i is its
                        upwind cell, + that of fa; then - the outflows whose far cell is missing (their pair
                        falls on the diagonal), fb's before fa's; axis after axis, in one sum;
    (i, cell below):    - inflow of fb if it flows into i, then - outflow of fa if i is fa's upwind cell (its
                        far cell is the one below i);
    (i, cell above):    the mirror image;

then the diffusion (own[i] on the diagonal, `neighbour` off it) added to that sum, and 1/dt to the diagonal.
Every entry is the face-by-face form's bit for bit (tests/test_parallel.py compares the whole step's matrix with
the whole-array numpy form, tests/test_kernels.py that form with `advection_into`).  At 40^3 (TVD, one thread)
the matrix with its right-hand side took 4.7 ms face by face and 2.7 ms row by row (benchmarks/step_parts.py).
A face on the border of two blocks of rows is made by both blocks (the same bits), each before reading it.
"""
from __future__ import annotations

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True)


@jit
def face_coefficients(inflow: np.ndarray, outflow: np.ndarray, forward: np.ndarray, offset: int, faces: np.ndarray,
                      w: np.ndarray, phi: np.ndarray, h: float, tvd: bool, first: int, last: int) -> None:
    """For faces first .. last - 1 of one axis (faces: (4, m) lower, upper, lower_out, upper_out), at offset + f:
    the inflow coefficient |w|(1 - psi/2)/h, TVD's outflow coefficient |w| (psi/r)/2 / h (0 for upwind) and
    whether the face flows from lower to upper (w > 0): `kernels.advection_into`'s arithmetic."""
    for f in range(first, last):
        a = abs(w[f]) / h
        ahead = w[f] > 0
        forward[offset + f] = ahead
        if not tvd:
            inflow[offset + f] = a
            outflow[offset + f] = 0.0
            continue
        up, down, far = (faces[0, f], faces[1, f], faces[2, f]) if ahead else (faces[1, f], faces[0, f], faces[3, f])
        num = phi[up] - phi[far] if far >= 0 else 0.0
        den = phi[down] - phi[up]
        if num * den > 0:
            total = num + den
            psi, psi_over_r = 2.0 * num / total, 2.0 * den / total
        else:
            psi, psi_over_r = 0.0, 0.0
        inflow[offset + f] = a * (1.0 - 0.5 * psi)
        outflow[offset + f] = a * 0.5 * psi_over_r


@jit
def matrix_rows(data: np.ndarray, indptr: np.ndarray, diagonal: np.ndarray, neighbour: float, own: np.ndarray,
                reciprocal: float, diagonal_out: np.ndarray, below: np.ndarray, above: np.ndarray,
                lower_entry: np.ndarray, upper_entry: np.ndarray, inflow: np.ndarray, outflow: np.ndarray,
                forward: np.ndarray, tvd: bool, start: int, stop: int) -> None:
    """Rows start .. stop - 1 of the phi matrix (module docstring): below/above (ndim, n) the face under and over
    each cell per axis (-1: none), lower_entry/upper_entry (ndim, n) where the entries of the cells under and over
    it are in `data`; the diagonal's values also to `diagonal_out`."""
    for i in range(start, stop):
        for k in range(indptr[i], indptr[i + 1]):
            data[k] = neighbour + 0.0
        total = 0.0
        for axis in range(below.shape[0]):
            fb, fa = below[axis, i], above[axis, i]
            into_b = fb >= 0 and forward[fb]  # fb flows from the cell below into i
            into_a = fa >= 0 and not forward[fa]  # fa flows from the cell above into i
            out_b = fb >= 0 and not forward[fb]  # i is fb's upwind cell
            out_a = fa >= 0 and forward[fa]
            if into_b:
                total += inflow[fb]
            if into_a:
                total += inflow[fa]
            if tvd:
                if out_b:
                    total += outflow[fb]
                if out_a:
                    total += outflow[fa]
                if out_b and fa < 0:  # fb's far cell (above i) is missing: its pair is the diagonal
                    total -= outflow[fb]
                if out_a and fb < 0:
                    total -= outflow[fa]
            if fb >= 0:
                entry = 0.0
                if into_b:
                    entry -= inflow[fb]
                if tvd and out_a:
                    entry -= outflow[fa]
                data[lower_entry[axis, i]] = neighbour + entry
            if fa >= 0:
                entry = 0.0
                if into_a:
                    entry -= inflow[fa]
                if tvd and out_b:
                    entry -= outflow[fb]
                data[upper_entry[axis, i]] = neighbour + entry
        d = diagonal[i]
        data[d] = own[i] + total
        data[d] += reciprocal
        diagonal_out[i] = data[d]


def face_maps(faces: list, indptr: np.ndarray, offsets: list[np.ndarray], n: int):
    """(below, above, lower_entry, upper_entry), each (ndim, n) (`matrix_rows`), and the offset of each axis's faces
    in one numbering of all faces, from the faces' (4, m) cells and their entries' offsets in their rows (6, m:
    `Biofilm.offsets`, entries 2 (upper, lower) and 3 (lower, upper))."""
    ndim = len(faces)
    below, above = np.full((ndim, n), -1, np.int64), np.full((ndim, n), -1, np.int64)
    lower_entry, upper_entry = np.full((ndim, n), -1, np.int64), np.full((ndim, n), -1, np.int64)
    starts = np.cumsum([0] + [f.shape[1] for f in faces])
    for axis, (cells, entries) in enumerate(zip(faces, offsets)):
        lower, upper = cells[0].astype(np.int64), cells[1].astype(np.int64)
        numbers = starts[axis] + np.arange(cells.shape[1])
        above[axis, lower], below[axis, upper] = numbers, numbers
        lower_entry[axis, upper] = indptr[upper] + entries[2]
        upper_entry[axis, lower] = indptr[lower] + entries[3]
    return below, above, lower_entry, upper_entry, starts
