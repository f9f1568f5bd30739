"""The growth term of Eq. 34 as motion of the biofilm front, its speed extended along the normals.

Eq. 34's growth term |grad phi| r c/(k+c) n_phi . n_c moves every level set of
phi with the normal speed

    F = r c/(k+c) N . n_c,      N = -grad phi / |grad phi|  (outward normal),

which is what the pointwise velocity v = r c/(k+c) n_c does (`biofilm.Velocity`).
Near the nutrient minimum n_c turns round, so v diverges there and the phi
found at the minimum is spread in every direction.  While the minimum lies in
dense biofilm the value spread is ~1 and the colony stays dense; once it lies
in the colony's diffuse edge, or on a wall the colony has reached, a partial
phi spreads and the colony dissolves.  Refined runs show the model itself
doing so late in a run; on 1 µm cells the smeared front's own consumption
pulls the minimum into it within T* ~ 0.2 (docs/paper.md has the measurements).

The front velocity computes the sharp-interface limit instead, by the velocity
extension of level-set numerics: the speed is taken where the front is and
carried along the normals, so that the front's profile translates and the
dense side moves with it.  Here:

1. The front is the phi = 1/2 level, located on every face whose two cells lie
   on either side of it, by linear interpolation (sub-cell).  There c, grad c
   and grad phi are interpolated from the cells (central differences; the
   face-normal component of grad phi from the two cells), and F is evaluated
   with the same regularised direction n_c = grad c / max(|grad c|, floor)
   as the pointwise velocity.  The crossing's cell (the nearer of the two)
   holds the vector F N (averaged over its crossings).
2. Every cell on the dense side (phi >= 1/2) and every cell within `band`
   cells of a front cell takes the vector of its nearest front cell, nearest
   along paths through open cells from face to face (obstacles are walls: a
   front does not lend its speed to the corridor behind one); a face between
   two such cells gets the mean of their vectors' normal components.  The
   interior no longer sees the nutrient minimum; where the vectors of two
   fronts meet inside it (the medial axis) the value spread is the interior's.
   (A band on the dense side too moves the spreading to the band's edge, where
   the smeared profile is not yet 1: measured, it diluted the agar colony.)
3. Elsewhere - the void beyond the band, or everywhere when phi nowhere
   reaches 1/2 (a thin, diluted film) - the pointwise velocity is kept.

The advection itself (upwind or TVD, implicit, bounded) is unchanged: only the
velocity field differs.  Where a front is wide and resolved (large beta against
h, as in the maze's Table 6) the pointwise velocity is the better choice: a
rigidly moved profile has no spreading at its minimum, and diffusion alone
then thins a colony that the model as written keeps.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from ..parallel import SERIAL, Team
from ..parallel.rows import blocks, split_each
from .finite_volume import FiniteVolumeGrid
from .kernels import extended_faces, front_crossings, nearest_rows, subgraph, within_reach

LEVEL = 0.5  # the front: phi = 1/2


class FrontVelocity:
    """Face velocities (µm/T*) per axis from c and phi: pointwise far from the front, extended near it."""

    def __init__(self, fv: FiniteVolumeGrid, pointwise, band: float = 3.0, team: Team = SERIAL,
                 adjacency: tuple[np.ndarray, np.ndarray] | None = None):
        self.fv = fv
        self.team = team
        self.rows = blocks(fv.n, team)  # the team's blocks of cells, and per axis the faces that touch each
        self.face_ranges = fv.face_ranges(self.rows)
        self.pointwise = pointwise  # a biofilm.Velocity: r, k, floor, cell gradients
        self.band = band
        if adjacency is None:  # open cells sharing a face (each at distance h): the Laplacian's pattern
            adjacency = fv.laplacian.indptr, fv.laplacian.indices
        self.adjacency = adjacency  # (indptr, indices) of a CSR pattern whose off-diagonal entries are those cells

    def __call__(self, c: np.ndarray, phi: np.ndarray) -> list[np.ndarray]:
        w, gradient, floor = self.pointwise.field(c)
        if floor == 0.0:
            return w  # r = 0 or a flat nutrient: no growth anywhere
        vectors, front = self._front(c, phi, gradient, floor)
        if front.size == 0:
            return w
        nearest = self._nearest(front, phi >= LEVEL)
        # a face beside a covered cell: the mean of its cells' normal components (one of them where only one is)
        extended = [np.empty(wf.size) for wf in w]
        faces = self.fv.faces
        split_each(self.team, [wf.size for wf in w], lambda k, a, b: extended_faces(
            extended[k], w[k], faces[k].lower, faces[k].upper, faces[k].axis, nearest, vectors, a, b))
        return extended

    def _front(self, c: np.ndarray, phi: np.ndarray, gradient: np.ndarray, floor: float):
        """The vector F N per front cell (rows of `vectors`) and the front cells' active indices, with the
        pointwise velocity's cell gradient of c and floor of |grad c| (the same regularised direction); a
        cell owning several crossings holds their mean (kernels.front_crossings)."""
        fv, velocity = self.fv, self.pointwise
        grad_phi = velocity.central_differences(phi)
        sums = np.zeros((fv.n, fv.grid.ndim))
        count = np.zeros(fv.n, np.int64)
        rows, faces = self.rows, self.face_ranges

        def block(p: int) -> None:  # the crossings owned by a block's cells, axis after axis as at once
            if p + 1 < rows.size:
                for f, ranges in zip(fv.faces, faces):
                    front_crossings(sums, count, f.lower, f.upper, f.axis, c, phi, gradient, grad_phi, LEVEL,
                                    fv.grid.spacing, velocity.r, velocity.k, floor, ranges[p, 0], ranges[p, 1],
                                    rows[p], rows[p + 1])

        self.team.run(block) if rows.size > 2 else block(0)
        front = np.flatnonzero(count)
        return sums[front] / count[front, None], front

    def _nearest(self, front: np.ndarray, dense: np.ndarray) -> np.ndarray:
        """For every active cell, the row in `front` of its nearest front cell, by paths through open cells
        (obstacles are walls), if the cell is on the dense side (phi >= 1/2) or within `band` cells of the front;
        else -1.  Dijkstra on the cells that can qualify: the dense ones and the front's dilation by the band."""
        fv = self.fv
        grown = within_reach(fv.cells[front], np.asarray(fv.grid.cells_shape, np.int64), int(np.ceil(self.band)))
        keep = dense | grown[fv.cells]
        candidates = np.flatnonzero(keep)
        local = np.full(fv.n, -1, np.int32)
        local[candidates] = np.arange(candidates.size, dtype=np.int32)
        indptr, indices = self.adjacency  # its rows and columns of the candidates: adjacency[candidates][:, candidates]
        kept = np.empty(indices.size, np.int32)
        indptr = subgraph(indptr, indices, keep, local, kept)
        graph = sp.csr_matrix((np.full(indptr[-1], fv.grid.spacing), kept[:indptr[-1]], indptr),
                              shape=(candidates.size,) * 2)
        distance, _, source = dijkstra(graph, directed=True, indices=local[front], min_only=True,
                                       return_predecessors=True)
        return nearest_rows(fv.n, front, candidates, dense, distance, source,
                            self.band * fv.grid.spacing * (1 + 1e-9))
