"""The growth front's Courant number, and the step that keeps it within the limit of the phi step.

The phi step (biofilm.py) is implicit Euler with the advection in positive-coefficient form: bounded for any
step, so no step is unstable.  But three parts of it are explicit (step.py): the growth velocity comes from
c^n and, with the front velocity, from the front of phi^n; the nutrient is solved for phi^n; TVD's limiter
is lagged at phi^n.  A step in which the front crosses more than one cell moves it through cells whose
nutrient and direction were computed without it, and implicit Euler's own error, the numerical diffusion
|v|^2 dt / 2 it adds to the advection, exceeds upwinding's |v| h / 2 (docs/model.md, "Clocks").  Both say the
same: the front may cross at most one cell per step.

The Courant number of a step dt is dt times the largest rate at which the discrete velocity fills a cell,
max over cells of sum over its inflow faces |w_f| / h: the implicit operator's diagonal for upwinding, and
|v| dt / h (cells crossed) for a front moving along an axis.  Since |w_f| <= r c_f/(k + c_f) <= r max c/(k +
max c), it is at most ndim r dt max c/(k + c) / h, the front speed's bound.  The source k_alpha alpha^n of the
phi step is explicit too: k_alpha dt <= LIMIT keeps a step in which the expansion feedback (phi and alpha
growing together as e^(k_alpha t), Eqs. 34 and 36) grows at most e-fold.  The clock (`timeloop.Clock`) splits a
step beyond either limit into equal substeps, and keeps to the shortest such step a run has needed (docs/model.md,
"Clocks", says why).
"""
from __future__ import annotations

import numpy as np

from .finite_volume import FiniteVolumeGrid
from .kernels import add_inflow, largest_quotient

LIMIT = 1.0  # cells the front may cross per step (and e-folds of the expansion source)


def courant_rate(fv: FiniteVolumeGrid, w: list[np.ndarray]) -> float:
    """The Courant number of a unit step (1/T*): a step dt has Courant number dt * courant_rate.  It is the largest
    over cells of the sum over a cell's inflow faces of |w_f| / h (w_f > 0 flows from a face's lower cell into
    its upper one), made axis by axis (`kernels.add_inflow`)."""
    rate, scratch = np.zeros(fv.n), np.empty(fv.n)
    for face, wf in zip(fv.faces, w):
        add_inflow(rate, scratch, face.lower, face.upper, np.asarray(wf, dtype=float))
    return float(largest_quotient(rate, fv.grid.spacing))
