"""Local expansion alpha (paper Eq. 36): d alpha / dt = k_alpha phi.

Integrated with the step's new phi (alpha^{n+1} = alpha^n + dt k_alpha
phi^{n+1}) while the phi step used alpha^n as its source: together a
symplectic-Euler step of the linear pair (phi, alpha), first order in dt.
alpha >= 0 wherever phi >= 0.  Nothing else feeds on alpha but the growth
mechanics (Fg = (1 + alpha) I).
"""
from __future__ import annotations

import numpy as np


def grow(alpha: np.ndarray, phi: np.ndarray, k_alpha: float, dt: float) -> np.ndarray:
    """alpha after a step of length dt with biofilm density phi (Eq. 36)."""
    return alpha + dt * k_alpha * phi
