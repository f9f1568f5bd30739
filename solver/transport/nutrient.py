"""Nutrient concentration c: paper Eq. 35, quasi-steady (time homogenisation) or transient.

The nutrient diffuses orders of magnitude faster than the biofilm grows
(eta_c << eta_phi), so at every step c solves the steady problem

    first-order:  d lap(c) = g phi c                     (default; docs/model.md)
    zero-order:   d lap(c) = g phi  where c > 0,  c >= 0  (paper Eq. 35)

with zero flux on walls and obstacles and c held in the source cells and on
held boundary faces (a Dirichlet value half a cell from the cells beside the
face: a coefficient 2/h^2 on their diagonal).
Divided by d, with K = -lap restricted to the free cells and gamma = g/d:

    first-order:  (K + gamma diag(phi)) c = b                 an SPD M-matrix:
                  0 <= c <= max(held values) by the discrete maximum principle;
    zero-order:   c >= 0,  lambda = K c - b + gamma phi >= 0,  c lambda = 0,
                  the complementarity (obstacle) problem of minimising
                  1/2 c.K c - (b - gamma phi).c over c >= 0: consumption stops
                  where the nutrient is exhausted (lambda is the unmet demand).
                  Solved by a primal-dual active-set iteration, which ends in
                  finitely many steps for an M-matrix; never by clipping.

Transient (`[model] nutrient = "transient"`, Eq. 35 with dc/dt): backward
Euler over phi's step dt adds the mass m = 1/(d dt) to the diagonal and
m c^n to the right-hand side, (K + m + gamma diag(phi)) c = b + m c^n (and
the same complementarity with K + m): still an SPD M-matrix, so 0 <= c <=
max(held values) whatever the step.

Cells in a region no source can reach (walled off by obstacles) have c = 0.
Solver round-off within `ROUNDOFF` of a bound is projected onto it; anything
beyond is a failed step, reported with its place.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..counters import Counters
from ..errors import StepFailure
from ..parallel import SERIAL, Team
from ..problem import Consumption, Parameters
from .bounds import ROUNDOFF, Projection
from .finite_volume import FiniteVolumeGrid
from .linear import KeptDiagonal, ReusedAMG

MAX_ACTIVE_SET_ITERATIONS = 100


class Nutrient:
    """Solves for c on the active cells given phi; keeps its AMG hierarchy between calls."""

    def __init__(self, fv: FiniteVolumeGrid, params: Parameters, consumption: Consumption,
                 held: np.ndarray, value: np.ndarray, tolerance: float = 1e-10,
                 faces: tuple[tuple[str, float], ...] = (), team: Team = SERIAL):
        self.fv = fv
        self.consumption = consumption
        self.gamma = params.g / params.d
        self.d = params.d
        laplacian = fv.laplacian
        held_cells = fv.to_active(held).astype(bool)
        held_value = np.where(held_cells, fv.to_active(value), 0.0)
        self.faces = [(face, fv.boundary_cells(face), float(v)) for face, v in faces]
        face_coefficient, face_inflow = np.zeros(fv.n), np.zeros(fv.n)
        for _, cells, v in self.faces:
            face_coefficient[cells] += 2.0 / fv.grid.spacing**2
            face_inflow[cells] += 2.0 * v / fv.grid.spacing**2
        held = held_cells | self._unreachable(laplacian, held_cells | (face_coefficient > 0))
        self.free = np.flatnonzero(~held)
        self.upper = max([0.0, *held_value[held_cells], *(v for _, _, v in self.faces)])
        self.c_held = held_value
        lap_free = laplacian[self.free]
        stiffness = sp.csr_matrix(-lap_free[:, self.free] + sp.diags(face_coefficient[self.free]))  # K, SPD
        self.rhs = lap_free[:, np.flatnonzero(held)] @ held_value[held] + face_inflow[self.free]  # b: inflow
        del lap_free
        self.matrix = KeptDiagonal(stiffness, team, owned=True)  # K + gamma diag(phi), rewritten in place per solve
        self.amg = ReusedAMG(tolerance, team=team, places=fv.places(self.free))
        self.active_set = np.zeros(self.free.size, bool)  # zero-order: cells where c = 0
        self.active_set_iterations = 0
        self.projection = Projection()  # what _checked projected onto [0, upper]

    def counters(self) -> Counters:
        return {**self.amg.counters("nutrient"),
                "nutrient_active_set_iterations": self.active_set_iterations,
                **self.projection.counters("c")}

    @property
    def stiffness(self) -> sp.csr_matrix:
        """K: the kept matrix with no demand on its diagonal (until the next solve rewrites it)."""
        return self.matrix(np.zeros(self.free.size))

    @staticmethod
    def _unreachable(laplacian: sp.csr_matrix, sources: np.ndarray) -> np.ndarray:
        """Cells in connected regions that contain no source cell."""
        count, label = connected_components(laplacian, directed=False)
        fed = np.zeros(count, bool)
        fed[label[sources]] = True
        return ~fed[label]

    def prepare(self, phi: np.ndarray) -> None:
        """Build the hierarchy of the solve for `phi` (the first one of a run) ahead of it, where that solve would
        build it (first-order consumption, some inflow; quasi-steady: the transient's first solve has the mass on
        its diagonal)."""
        if self.free.size and self.consumption == "first-order" and np.any(self.rhs) and self.amg.cycle is None:
            self.amg.prepare(self.matrix(self.gamma * phi[self.free]))

    def solve(self, phi: np.ndarray, guess: np.ndarray | None = None, before: np.ndarray | None = None,
              dt: float = 0.0) -> np.ndarray:
        """c on the active cells for biofilm density `phi` (active cells); `guess` warm-starts CG (it changes
        the iterations, not the answer beyond the tolerance); `before`: c a step `dt` earlier, for the transient
        Eq. 35 (None: quasi-steady)."""
        c = self.c_held.copy()
        if self.free.size:
            x0 = None if guess is None else guess[self.free]
            demand = self.gamma * phi[self.free]
            mass = 0.0 if before is None else 1.0 / (self.d * dt)
            rhs = self.rhs if before is None else self.rhs + mass * before[self.free]
            if self.consumption == "first-order":
                c[self.free] = self.amg.solve(self.matrix(demand + mass), rhs, x0)
            else:
                c[self.free] = self._complementarity(demand, x0, mass, rhs)
        return self._checked(c)

    def _complementarity(self, demand: np.ndarray, x0: np.ndarray | None, mass: float = 0.0,
                         b: np.ndarray | None = None) -> np.ndarray:
        """Primal-dual active set for c >= 0, (K + mass) c - b + demand >= 0, complementary."""
        K = self.stiffness + mass * sp.identity(self.free.size, format="csr") if mass else self.stiffness
        b = self.rhs if b is None else b
        scale = max(float(np.abs(b).max(initial=0.0)), float(demand.max(initial=0.0)), 1e-300)
        active = self.active_set.copy()
        for iteration in range(1, MAX_ACTIVE_SET_ITERATIONS + 1):
            keep = (~active).astype(float)
            reduced = sp.diags(keep) @ K @ sp.diags(keep) + sp.diags(1.0 - keep)
            rhs = keep * (b - demand)
            c = self.amg.solve(sp.csr_matrix(reduced), rhs, None if x0 is None else keep * x0)
            c[active] = 0.0
            unmet = K @ c - b + demand
            new = np.where(active, unmet > -ROUNDOFF * scale, c < -ROUNDOFF * max(self.upper, 1e-300))
            if np.array_equal(new, active):
                self.active_set = active
                self.active_set_iterations += iteration
                return c
            active, x0 = new, c
        raise StepFailure(f"zero-order nutrient active set did not settle in {MAX_ACTIVE_SET_ITERATIONS} iterations")

    def _checked(self, c: np.ndarray) -> np.ndarray:
        """NaN and bounds check; round-off within ROUNDOFF is projected onto [0, upper]."""
        return self.projection.checked(c, self.upper, "nutrient c", self.fv.describe)
