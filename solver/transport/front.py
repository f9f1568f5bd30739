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
from scipy import ndimage
from scipy.sparse.csgraph import dijkstra

from .finite_volume import FiniteVolumeGrid

LEVEL = 0.5  # the front: phi = 1/2


class FrontVelocity:
    """Face velocities (µm/T*) per axis from c and phi: pointwise far from the front, extended near it."""

    def __init__(self, fv: FiniteVolumeGrid, pointwise, band: float = 3.0):
        self.fv = fv
        self.pointwise = pointwise  # a biofilm.Velocity: r, k, floor, cell gradients
        self.band = band
        lower = np.concatenate([f.lower for f in fv.faces])
        upper = np.concatenate([f.upper for f in fv.faces])
        weight = np.full(2 * lower.size, fv.grid.spacing)
        self.adjacency = sp.csr_matrix((weight, (np.concatenate([lower, upper]), np.concatenate([upper, lower]))),
                                       shape=(fv.n, fv.n))  # open cells sharing a face, distance h
        self.cross = ndimage.generate_binary_structure(fv.grid.ndim, 1)

    def __call__(self, c: np.ndarray, phi: np.ndarray) -> list[np.ndarray]:
        w, gradient, floor = self.pointwise.field(c)
        if floor == 0.0:
            return w  # r = 0 or a flat nutrient: no growth anywhere
        vectors, front = self._front(c, phi, gradient, floor)
        if front.size == 0:
            return w
        nearest = self._nearest(front, phi >= LEVEL)
        inside = nearest >= 0
        extended = np.zeros((self.fv.n, self.fv.grid.ndim))
        extended[inside] = vectors[nearest[inside]]
        faces = []
        for f, wf in zip(self.fv.faces, w):
            a, b = inside[f.lower], inside[f.upper]
            va, vb = extended[f.lower, f.axis], extended[f.upper, f.axis]
            mean = np.where(a & b, 0.5 * (va + vb), va + vb)  # one of them is 0 where only one is inside
            faces.append(np.where(a | b, mean, wf))
        return faces

    def _front(self, c: np.ndarray, phi: np.ndarray, gradient: list[np.ndarray], floor: float):
        """The vector F N per front cell (rows of `vectors`) and the front cells' active indices, with the
        pointwise velocity's cell gradient of c and floor of |grad c| (the same regularised direction)."""
        fv, h, velocity = self.fv, self.fv.grid.spacing, self.pointwise
        grad_c = np.stack(gradient, axis=1)
        grad_phi = np.stack(velocity.central_differences(phi), axis=1)
        owners, vectors = [], []
        for f in fv.faces:
            crossing = (phi[f.lower] >= LEVEL) != (phi[f.upper] >= LEVEL)
            if not crossing.any():
                continue
            a, b = f.lower[crossing], f.upper[crossing]
            theta = (phi[a] - LEVEL) / (phi[a] - phi[b])  # 0 at a, 1 at b
            t = theta[:, None]
            c_x = (1 - theta) * c[a] + theta * c[b]
            grad_c_x = (1 - t) * grad_c[a] + t * grad_c[b]
            grad_phi_x = (1 - t) * grad_phi[a] + t * grad_phi[b]
            grad_phi_x[:, f.axis] = (phi[b] - phi[a]) / h
            normal = -grad_phi_x / np.linalg.norm(grad_phi_x, axis=1)[:, None]
            direction = grad_c_x / np.maximum(np.linalg.norm(grad_c_x, axis=1), floor)[:, None]
            speed = velocity.r * c_x / (velocity.k + c_x) * np.einsum("ij,ij->i", normal, direction)
            owners.append(np.where(theta < 0.5, a, b))
            vectors.append(speed[:, None] * normal)
        if not owners:
            return np.zeros((0, fv.grid.ndim)), np.zeros(0, np.int64)
        owners, vectors = np.concatenate(owners), np.concatenate(vectors)
        front, slot = np.unique(owners, return_inverse=True)
        count = np.bincount(slot, minlength=front.size)
        mean = np.stack([np.bincount(slot, weights=vectors[:, i], minlength=front.size) / count
                         for i in range(vectors.shape[1])], axis=1)
        return mean, front

    def _nearest(self, front: np.ndarray, dense: np.ndarray) -> np.ndarray:
        """For every active cell, the row in `front` of its nearest front cell, by paths through open cells
        (obstacles are walls), if the cell is on the dense side (phi >= 1/2) or within `band` cells of the front;
        else -1.  Dijkstra on the cells that can qualify: the dense ones and the front's dilation by the band."""
        fv = self.fv
        reach = int(np.ceil(self.band))
        near = np.zeros(fv.n, bool)
        near[front] = True
        grown = ndimage.binary_dilation(fv.to_full(near.astype(float), fill=0.0) > 0, structure=self.cross,
                                        iterations=reach)
        candidates = np.flatnonzero(dense | fv.to_active(grown).astype(bool))
        local = np.full(fv.n, -1, np.int64)
        local[candidates] = np.arange(candidates.size)
        graph = self.adjacency[candidates][:, candidates]
        distance, _, source = dijkstra(graph, directed=True, indices=local[front], min_only=True,
                                       return_predecessors=True)
        row = np.full(fv.n, -1, np.int64)
        row[front] = np.arange(front.size)
        found = source >= 0
        covered = found & (dense[candidates] | (distance <= self.band * fv.grid.spacing * (1 + 1e-9)))
        nearest = np.full(fv.n, -1, np.int64)
        nearest[candidates[covered]] = row[candidates[source[covered]]]
        return nearest
