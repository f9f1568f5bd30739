"""Growth hyperelasticity at quadrature points: plain arrays in, plain arrays out.

Kinematics (paper 2.1, Eq. 1): F = Fe Fg with isotropic growth
Fg = (1 + alpha) I, so Jg = (1 + alpha)^3 and Je = J / Jg.  Because Fg is
spherical, the isochoric part of Fe equals that of F:
C~e = Je^(-2/3) Fe^T Fe = J^(-2/3) F^T F, and growth enters the energy only
through the volume ratio.

Energy (paper Eq. 20 with the constraint Eq. 15 condensed by a perturbed
Lagrangian, docs/mechanics.md), per unit volume of the grown (intermediate)
configuration, each part weighted by w = eps + (1 - eps) phi^2:

    psi = w mu / 2 (tr C~e - 3)  +  w kappa / 2 (Je - 1)^2.

Integrated over the reference cell this is Jg psi dV, which makes the Cauchy
stress sigma = Je^-1 dpsi/dFe Fe^T (paper Table 1, step 2): the hydrostatic
part is p = w kappa (Je - 1), so p = kappa ((1 + alpha)^-3 - 1) when all
motion is prevented.  The isochoric Cauchy stress is trace-free, so p is the
whole of tr(sigma) / 3.

Q1/P0 mean dilatation (Simo, Taylor & Pister 1985; the paper's "H1P0",
section 3): the volumetric part uses the element's mean elastic volume ratio
Theta = (1/V) int J dV / Jg instead of the pointwise Je, i.e. the element
pressure p = w kappa (Theta - 1), eliminated by static condensation (paper
Table 1, step 7).  This module holds the pointwise pieces; `assembly` adds
the element-level ones.

Arrays: F has shape (..., 3, 3) (plane strain: F[..., 2, 2] = 1); the
tangent dP_iJ/dF_kL is never formed, only its scalar coefficients
(`tangent_coefficients`), which broadcast against the leading dimensions.
The tests check residual and tangent against central differences of the
energy and the residual.
"""
from __future__ import annotations

import numpy as np


def determinant(F: np.ndarray) -> np.ndarray:
    """det F for a stack of 3x3 matrices (closed form: no LAPACK call per point)."""
    return (F[..., 0, 0] * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
            - F[..., 0, 1] * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
            + F[..., 0, 2] * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0]))


def cofactor(F: np.ndarray) -> np.ndarray:
    """cof F = J F^-T = dJ/dF."""
    c = np.empty_like(F)
    c[..., 0, 0] = F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1]
    c[..., 0, 1] = F[..., 1, 2] * F[..., 2, 0] - F[..., 1, 0] * F[..., 2, 2]
    c[..., 0, 2] = F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0]
    c[..., 1, 0] = F[..., 0, 2] * F[..., 2, 1] - F[..., 0, 1] * F[..., 2, 2]
    c[..., 1, 1] = F[..., 0, 0] * F[..., 2, 2] - F[..., 0, 2] * F[..., 2, 0]
    c[..., 1, 2] = F[..., 0, 1] * F[..., 2, 0] - F[..., 0, 0] * F[..., 2, 1]
    c[..., 2, 0] = F[..., 0, 1] * F[..., 1, 2] - F[..., 0, 2] * F[..., 1, 1]
    c[..., 2, 1] = F[..., 0, 2] * F[..., 1, 0] - F[..., 0, 0] * F[..., 1, 2]
    c[..., 2, 2] = F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    return c


def isochoric_energy(J: np.ndarray, I1: np.ndarray, shear) -> np.ndarray:
    """shear/2 (J^(-2/3) I1 - 3), I1 = tr(F^T F); `shear` = Jg w mu (per unit reference volume)."""
    return 0.5 * shear * (J ** (-2.0 / 3.0) * I1 - 3.0)


def tangent_coefficients(J: np.ndarray, I1: np.ndarray, shear, pressure):
    """The pointwise tangent dP/dF at fixed pressure, as scalars times products of F and G = F^-T.

    P = s (F - I1/3 G) + p J G is the first Piola-Kirchhoff stress (isochoric part plus a Cauchy
    pressure p; the change of the element pressure itself is `assembly`'s rank-one term).  With
    s = shear J^(-2/3):
        dP_iJ/dF_kL = s d_ik d_JL + c_fg (F_kL G_iJ + G_kL F_iJ) + c_gg G_iJ G_kL + c_swap G_iL G_kJ,
        c_fg = -2/3 s,   c_gg = 2/9 s I1 + p J,   c_swap = s I1/3 - p J.
    Contracted with basis gradients these become outer products of per-node vectors,
    which is how the element matrices are built without forming 81 numbers per point.
    Returns (s, c_fg, c_gg, c_swap).
    """
    s = shear * J ** (-2.0 / 3.0)
    pJ = pressure * J
    return s, -2.0 / 3.0 * s, 2.0 / 9.0 * s * I1 + pJ, s * I1 / 3.0 - pJ


def weight(phi: np.ndarray, residual_stiffness: float) -> np.ndarray:
    """w = eps + (1 - eps) phi^2: the paper's phi^2 with void cells kept solvable.

    Scaling shear and bulk together (rather than adding eps to phi^2) leaves
    w = 1 exactly where phi = 1, so the dense-biofilm exact solutions hold.
    """
    return residual_stiffness + (1.0 - residual_stiffness) * np.asarray(phi, dtype=float) ** 2
