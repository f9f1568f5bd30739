"""The pressure a dataset holds: Q1/P0's element pressure, or the same without its spurious modes.

Q1/P0 (the paper's H1P0, section 3) is not inf-sup stable.  On a grid of
cubes its spurious pressure modes are the patterns that alternate along at
least two axes: in 2-D the checkerboard (-1)^(i+j), in 3-D also the plane
checkerboards (-1)^(i+j), (-1)^(j+k), (-1)^(i+k) and (-1)^(i+j+k).  Around
every interior node they do no work on any Q1 displacement (the face fluxes
of div u cancel in pairs), so the equilibrium does not control them, and
the element pressure p_e = w kappa (Theta_e - 1) carries them wherever the
pressure is rough: next to the corners of a rigid square in a clamped block,
and still several cells away (benchmarks/mechanics_pressure.py).

Recovery ("recovered", the default) removes exactly those patterns, locally
(pressure filtering in the spirit of Sani, Gresho, Lee & Griffiths 1981):

    c_n^m = 2^-d sum_(cells e around node n) s^m_e p_e        amplitude of pattern m at node n
    p~_e  = p_e - mean_(corners n of e) tau_n sum_m s^m_e c_n^m

over the spurious patterns m (signs s^m relative to the node) and the
interior nodes whose 2^d cells are all open.  Why this form:

* consistent with the displacement: only modes the discrete equilibrium
  cannot see are changed, so p~ exerts the same nodal forces as p_e up to
  O(h^2); it is exact wherever p_e is uniform (clamped growth
  p = kappa((1+alpha)^-3 - 1), free growth p = 0: to round-off);
* accurate: a smooth field changes only through its mixed second
  derivatives, by O(h^2) (h^2/4 d2p/dxdy): below Q1/P0's own O(h) error; the
  sphere's refinement series converges as fast as the element pressure's;
* it respects the biofilm/void interface: tau_n = min w / max w over the
  node's cells, so a jump of stiffness (and of pressure) is not mistaken for
  a checkerboard and no biofilm pressure leaks into the void;
* cheap: a few array slices per snapshot; nothing in the solve changes.

What it does not remove: spurious content at nodes on the boundary or next
to an obstacle (their cell stars are incomplete), so right at re-entrant
corners some of the checkerboard remains (measured in docs/mechanics.md).
"""
from __future__ import annotations

import itertools

import numpy as np

from .mesh import StructuredMesh


def spurious_patterns(ndim: int) -> tuple[list[tuple[int, ...]], np.ndarray]:
    """The 2^ndim cell offsets around a node and the signs (patterns, offsets) of the spurious modes."""
    offsets = list(itertools.product((0, 1), repeat=ndim))
    axes = [a for a in itertools.product((0, 1), repeat=ndim) if sum(a) >= 2]  # alternating along >= 2 axes
    signs = np.array([[(-1) ** int(np.dot(a, o)) for o in offsets] for a in axes], dtype=float)
    return offsets, signs


class PressureRecovery:
    """The filter on one mesh: which cells are open is fixed, the stiffness comes per call."""

    def __init__(self, mesh: StructuredMesh):
        self.mesh = mesh
        self.open = ~mesh.obstacle
        self.offsets, self.signs = spurious_patterns(mesh.ndim)
        self.nodes_inner = tuple(n - 1 for n in self.open.shape)  # interior nodes, grid order
        self.complete = np.logical_and.reduce([self._star(self.open, o) for o in self.offsets])
        count = np.zeros(self.open.shape)
        for o in self.offsets:
            count[self._at(o)] += self.complete
        self.count = np.maximum(count, 1)

    def _at(self, offset) -> tuple[slice, ...]:
        """The cells at `offset` of every interior node, as a slice of the cell grid."""
        return tuple(slice(a, a + m) for a, m in zip(offset, self.nodes_inner))

    def _star(self, cells: np.ndarray, offset) -> np.ndarray:
        return cells[self._at(offset)]

    def recover(self, pressure: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """Per element: the element pressure without spurious modes (weight: stiffness w per element)."""
        mesh = self.mesh
        p, w = np.zeros(mesh.grid.n_cells), np.ones(mesh.grid.n_cells)
        p[mesh.cells], w[mesh.cells] = pressure, weight
        p, w = p.reshape(self.open.shape), w.reshape(self.open.shape)
        star_p = np.stack([self._star(p, o) for o in self.offsets])  # (2^d, interior nodes)
        star_w = np.stack([self._star(w, o) for o in self.offsets])
        tau = np.where(self.complete, star_w.min(axis=0) / star_w.max(axis=0), 0.0)
        amplitude = np.tensordot(self.signs, star_p, axes=1) / len(self.offsets) * tau  # (patterns, nodes)
        correction = np.zeros(p.shape)
        for k, o in enumerate(self.offsets):  # the cell at offset o of node n: sum_m s^m_o c^m_n
            correction[self._at(o)] += np.tensordot(self.signs[:, k], amplitude, axes=1)
        return (p - correction / self.count).ravel()[mesh.cells]
