"""What the Jacobian at the optimum says: covariance, standard errors, correlations, a band for the fitted model.

With residuals weighted by the measurements' own sigma, the Gauss-Newton
covariance of the parameters is C = (J^T J)^-1 (no rescaling by chi²/dof:
the sigmas are given, and chi² against its degrees of freedom is how they
are checked).  Standard errors are sqrt(diag C) in the fit's coordinates (the
unit cube of the bounds), converted to the parameter's own scale (log10 for
log bounds) and, to first order, to its units.  The band of a fitted
observable is model_i ± 1.96 sigma_i sqrt(J_i C J_i^T): where 95 % of the
model curves of parameters drawn from that covariance lie.  All of it is
local: the profile likelihoods (`profiles`) are what the intervals come from.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Z95 = 1.959963984540054  # two-sided 95 % of a normal distribution
SINGULAR = 1e12  # condition number of J^T J beyond which the parameters are not separated by the data


@dataclass(frozen=True)
class Local:
    """Covariance in the unit cube, standard errors there, correlations (NaN where J^T J cannot be inverted)."""

    covariance: np.ndarray
    standard_error: np.ndarray
    correlation: np.ndarray


def local(jacobian: np.ndarray) -> Local:
    """C = (J^T J)^-1 from the weighted residuals' Jacobian (columns: unit-cube coordinates)."""
    k = jacobian.shape[1]
    normal = jacobian.T @ jacobian
    scale = np.sqrt(np.diag(normal))
    if np.any(scale == 0) or np.linalg.cond(normal / np.outer(scale, scale)) > SINGULAR:
        nan = np.full((k, k), np.nan)
        standard = np.where(scale == 0, np.inf, np.nan)
        return Local(nan, standard, nan)
    covariance = np.linalg.inv(normal)
    standard = np.sqrt(np.diag(covariance))
    return Local(covariance, standard, covariance / np.outer(standard, standard))


def band(jacobian: np.ndarray, covariance: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Half width of the 95 % band of each fitted model value: 1.96 sigma_i sqrt(J_i C J_i^T)."""
    if np.isnan(covariance).any():
        return np.full(jacobian.shape[0], np.nan)
    variance = np.einsum("ij,jk,ik->i", jacobian, covariance, jacobian)
    return Z95 * sigma * np.sqrt(np.maximum(variance, 0.0))


def natural(unit_error: float, low: float, high: float, log: bool, value: float) -> tuple[float, float]:
    """(error on the parameter's own scale: log10 units for log bounds, else its units; error in its units, to
    first order) of a unit-cube standard error."""
    if not math.isfinite(unit_error):
        return unit_error, unit_error
    if log:
        scaled = unit_error * (math.log10(high) - math.log10(low))
        return scaled, value * math.log(10.0) * scaled
    scaled = unit_error * (high - low)
    return scaled, scaled
