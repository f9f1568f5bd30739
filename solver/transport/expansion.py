"""Local expansion alpha: paper Eq. 36, or the local equation of the paper's algorithm (its Table 1).

Eq. 36 (`grow`, `[model] expansion = "eq36"`): d alpha / dt = k_alpha phi,
integrated with the step's new phi (alpha^{n+1} = alpha^n + dt k_alpha
phi^{n+1}) while the phi step used alpha^n as its source: together a
symplectic-Euler step of the linear pair (phi, alpha), first order in dt.
alpha >= 0 wherever phi >= 0 and grows for as long as there is biofilm.

Table 1, step 3a (`table1`, `[model] expansion = "table1"`): the residual

    R_alpha = (alpha' - alpha) / ((1 + alpha') dt) - k_alpha (phi' - phi) / (eta_alpha dt) = 0

solved exactly: with s = k_alpha (phi' - phi), 1 + alpha' = (1 + alpha) / (1 - s).
Read with k_alpha / eta_alpha = k_alpha, the k_alpha of Eq. 36: the paper sets
eta_alpha = eta_phi so that "k_alpha stays the same in Eq. 34 and in Eq. 36",
and only so is the residual's second term a rate per T* like its first (with
eta_alpha = 1e-10 as a number it would be 1e10 times k_alpha and have no
solution for any change of phi above 1e-7).  Then alpha changes only where phi
changes: ln(1 + alpha) = k_alpha (phi - phi_0) in the limit dt -> 0, so alpha
stays within about k_alpha of 0, and falls (alpha < 0) where biofilm leaves.
Each step needs s < 1 (otherwise no alpha' > -1 solves it): a step that asks
more fails and is bisected.  Per step |ln(1 + alpha') - ln(1 + alpha)| =
|ln(1 - s)| <= |s| / (1 - |s|), so over a run
|ln(1 + alpha)| <= k_alpha TV(phi) / (1 - k_alpha max|phi' - phi|),
TV(phi) the total variation of the cell's phi over time.
Nothing else feeds on alpha but phi's source k_alpha alpha and the growth
mechanics (Fg = (1 + alpha) I).
"""
from __future__ import annotations

import numpy as np

from ..errors import StepFailure


def grow(alpha: np.ndarray, phi: np.ndarray, k_alpha: float, dt: float) -> np.ndarray:
    """alpha after a step of length dt with biofilm density phi (Eq. 36)."""
    return alpha + dt * k_alpha * phi


def table1(alpha: np.ndarray, phi_before: np.ndarray, phi: np.ndarray, k_alpha: float,
           describe=lambda index: f"cell {index}") -> np.ndarray:
    """alpha' solving Table 1's R_alpha = 0 for the step that took phi_before to phi (no dt: it cancels);
    raises StepFailure where k_alpha (phi - phi_before) >= 1 (no solution; the clock bisects the step)."""
    s = k_alpha * (phi - phi_before)
    if np.any(s >= 1.0):
        where = int(np.argmax(s))
        raise StepFailure(f"Table 1's expansion has no solution: k_alpha (phi' - phi) = {s[where]:.3g} >= 1",
                          describe(where))
    return (alpha + s) / (1.0 - s)
