"""What a fit minimises: -2 log L of Gaussian measurement noise, σ given per measurement (chi²) or estimated,
one σ per noise parameter shared by its measurements, by maximum likelihood with the model's parameters.

The residuals arrive as r_i = (model_i - measurement_i) / d_i: d_i is the measurement's σ where the table gives
it, and a fixed scale of its group (`Likelihood.scales`, in the measurements' units) where σ is estimated. With
group g's rows (`groups[g]`, n_g of them), SS_g = Σ r_i² over them and σ_g in the measurements' units,

    -2 log L = Σ_given r_i² + Σ_g [ scale_g² SS_g / σ_g² + 2 n_g log σ_g ] + constant.

For fixed parameters it is smallest at σ̂_g² = scale_g² SS_g / n_g, exactly, so σ is profiled out analytically:

    F = Σ_given r_i² + Σ_g n_g (1 + log(scale_g² SS_g / n_g))

(the constant n log 2π + Σ_given log σ_i² left out).  Without groups F is chi², to the bit.  F's gradient and
Gauss-Newton Hessian at a point are those of chi² with the group rows weighted by 1/σ̂_g there (`weighted`):
Levenberg-Marquardt takes its steps from that model and accepts them, and judges convergence, on F itself; a
profile's threshold 3.84 applies to differences of F (σ re-estimated at every point).  The covariance from the
weighted Jacobian at the optimum is σ̂² (JᵀJ)⁻¹ for a group's rows: maximum likelihood's σ̂ (divided by n, not
n - k).

σ's own 95 % interval (`sigma_intervals`): where its profile, -2 log L at σ_g held, minimised over the
parameters and the other σs, stays within 3.84 of the optimum; the parameters are re-optimised on the model
linearised at the optimum (its Jacobian: no simulation), exact for a model linear in its parameters and for a
single group without other rows (whose best parameters do not depend on σ).  Maximum likelihood's intervals
assume σ̂ = σ, which few rows do not give: with n rows sharing σ and k parameters of a linear model they hold
the truth less often than 95 % (`coverage`: 87 % and 82 % for σ with 6 rows and 2 parameters).
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from scipy import stats
from scipy.optimize import brentq

PENALTY = 1e3  # each residual of a failed simulation
THRESHOLD = 3.841458820694124  # chi²(1) at 95 %
TINY = 1e-200  # SS_g / n_g (in units of the scale) is floored here: a model through every point of a group
# makes σ̂ = 0 and log L unbounded (`Likelihood.exact`; said in words, `calibration.report_noise`)
ITERATIONS = 100  # of the linearised re-optimisation in a σ profile (it converges monotonically: a majorisation)
NORMAL = sys.float_info.min  # below, a variance has lost digits or underflowed to 0
EXPANSIONS = 11  # brackets of a σ interval's end: log σ̂ ± 0.5, 1, 2, ..., 512


def chi2(residuals: np.ndarray) -> float:
    return float(np.sum(np.square(residuals)))


@dataclass(frozen=True)
class Likelihood:
    """-2 log L of the residuals (module docstring): chi² without `groups`; per group (the residuals' indices
    sharing one estimated σ) its σ profiled out, the group's residuals scaled by `scales` (measurement units)."""

    groups: tuple[np.ndarray, ...] = ()
    scales: tuple[float, ...] = ()

    def value(self, residuals: np.ndarray) -> float:
        """F: chi² of the rows with σ given plus, per group, n_g (1 + log σ̂_g²); a failed simulation's
        residuals (all `PENALTY`) are n · PENALTY² as without groups, above any finished simulation's F."""
        if not self.groups or np.all(residuals == PENALTY):
            return chi2(residuals)
        given = np.ones(len(residuals), dtype=bool)
        total = 0.0
        for rows, scale, variance in zip(self.groups, self.scales, self.variances(residuals)):
            given[rows] = False  # σ̂ at the floor of a σ̂-sized scale (`in_units_of`) underflows: log in two terms
            log_variance = math.log(variance) if variance >= NORMAL else \
                2.0 * math.log(scale) + math.log(self._mean_square(residuals, rows))
            total += len(rows) * (1.0 + log_variance)
        return chi2(residuals[given]) + total

    @staticmethod
    def _mean_square(residuals: np.ndarray, rows: np.ndarray) -> float:
        """SS_g / n_g, floored at `TINY`: σ̂_g² in units of the group's scale squared."""
        return max(chi2(residuals[rows]) / len(rows), TINY)

    def variances(self, residuals: np.ndarray) -> np.ndarray:
        """σ̂_g² per group, in the measurements' units: scale_g² SS_g / n_g."""
        return np.array([scale**2 * self._mean_square(residuals, rows)
                         for rows, scale in zip(self.groups, self.scales)])

    def weights(self, residuals: np.ndarray) -> np.ndarray:
        """Per residual the factor that puts it in units of σ: 1 where σ is given, scale_g / σ̂_g in a group."""
        weights = np.ones(len(residuals))
        for rows, variance, scale in zip(self.groups, self.variances(residuals), self.scales):
            weights[rows] = scale / math.sqrt(variance) if variance >= NORMAL else \
                1.0 / math.sqrt(self._mean_square(residuals, rows))
        return weights

    def exact(self, residuals: np.ndarray) -> list[bool]:
        """Per group: whether the model goes through every one of its rows (SS_g = 0, σ̂_g = 0: -2 log L is
        unbounded there, and σ_g cannot be estimated; the `TINY` floor keeps the fit's numbers finite)."""
        return [not np.any(residuals[rows]) for rows in self.groups]

    def weighted(self, residuals: np.ndarray, jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residuals and their Jacobian in units of σ (σ̂_g at these residuals for a group's rows); as given,
        the same arrays, without groups."""
        if not self.groups:
            return residuals, jacobian
        weights = self.weights(residuals)
        return residuals * weights, jacobian * weights[:, None]

    def sigmas(self, residuals: np.ndarray) -> np.ndarray:
        """σ̂_g per group, in the measurements' units."""
        return np.sqrt(self.variances(residuals))

    def in_units_of(self, sigmas: np.ndarray) -> Likelihood:
        """The same groups for residuals divided by `sigmas` instead of the scales (a `Fit`'s, weighted by σ̂)."""
        return Likelihood(self.groups, tuple(float(s) for s in sigmas))


@dataclass(frozen=True)
class Sigma:
    """An estimated σ (measurement units): maximum likelihood, its 95 % profile interval, its rows' count; an
    estimate 0 (NaN ends) where the model fits its rows exactly (`Likelihood.exact`)."""

    estimate: float
    lower: float
    upper: float
    rows: int

    @property
    def exact(self) -> bool:
        return self.estimate == 0.0


def coverage(rows: int, parameters: int) -> tuple[float, float]:
    """How often the 95 % profile intervals of the parameters and of σ hold the truth when `rows` measurements
    share one estimated σ and nothing else is measured, for a model linear in its `parameters` (exactly: the
    profile of a parameter is n log(1 + t² / (n - k)) with t Student's of n - k degrees of freedom, σ's
    n (v - log v - 1) with n v = n σ̂² / σ² chi² of n - k); NaN without a degree of freedom."""
    dof = rows - parameters
    if dof < 1:
        return math.nan, math.nan
    parameter = 1 - 2 * float(stats.t.sf(math.sqrt(dof * math.expm1(THRESHOLD / rows)), dof))
    rise = lambda v: rows * (v - math.log(v) - 1) - THRESHOLD  # noqa: E731 -- v = σ̂² / σ²
    low, high = brentq(rise, 1e-12, 1.0), brentq(rise, 1.0, 1e12)
    return parameter, float(stats.chi2.cdf(rows * high, dof) - stats.chi2.cdf(rows * low, dof))


def sigma_intervals(likelihood: Likelihood, residuals: np.ndarray, jacobian: np.ndarray,
                    free: np.ndarray) -> list[Sigma]:
    """Every group's σ̂ and 95 % profile interval at the optimum: `residuals` there as the likelihood reads them,
    `jacobian` theirs (d r / d u), `free` the coordinates the parameters may move along (the others held: at a
    bound).  A group the model fits exactly (`Likelihood.exact`) has σ̂ = 0 and no interval (NaN ends): its
    likelihood has no maximum to measure 3.84 from."""
    exact = likelihood.exact(residuals)
    return [Sigma(0.0, math.nan, math.nan, len(likelihood.groups[g])) if exact[g] else
            _interval(likelihood, g, residuals, jacobian[:, free]) for g in range(len(likelihood.groups))]


def _interval(likelihood: Likelihood, g: int, residuals: np.ndarray, jacobian: np.ndarray) -> Sigma:
    """Group g's σ̂ and where its profile crosses its minimum + `THRESHOLD` on either side (in log σ: brackets
    doubled outward from σ̂, then Brent's method); 0 or inf if it never does (a profile that stays flat)."""
    best = math.log(float(likelihood.sigmas(residuals)[g]))
    floor = _profile_at(likelihood, g, math.exp(best), residuals, jacobian)

    def rise(log_sigma: float) -> float:
        return _profile_at(likelihood, g, math.exp(log_sigma), residuals, jacobian) - floor - THRESHOLD

    ends = []
    for direction in (-1.0, 1.0):
        near = best
        for k in range(EXPANSIONS):
            far = best + direction * 0.5 * 2**k
            if rise(far) > 0:
                ends.append(math.exp(brentq(rise, min(near, far), max(near, far), xtol=1e-12)))
                break
            near = far
        else:
            ends.append(0.0 if direction < 0 else math.inf)
    return Sigma(math.exp(best), ends[0], ends[1], len(likelihood.groups[g]))


def _profile_at(likelihood: Likelihood, g: int, sigma: float, residuals: np.ndarray, jacobian: np.ndarray) -> float:
    """-2 log L with σ_g held at `sigma` (measurement units), minimised over the parameters on the linearised
    model r + J δ and over the other groups' σ (analytically): each step minimises the weighted least squares
    that majorises n_h log SS_h at the current δ, so -2 log L falls at every step."""
    rows = likelihood.groups[g]
    held = np.ones(len(residuals))
    held[rows] = likelihood.scales[g] / sigma  # group g's rows in units of the σ held
    others = Likelihood(likelihood.groups[:g] + likelihood.groups[g + 1:],
                        likelihood.scales[:g] + likelihood.scales[g + 1:])
    r0, moved = residuals * held, jacobian * held[:, None]

    def value(delta: np.ndarray) -> float:
        return others.value(r0 + moved @ delta) + 2 * len(rows) * math.log(sigma)

    delta = np.zeros(moved.shape[1])
    current = value(delta)
    for _ in range(ITERATIONS if moved.shape[1] else 0):
        weights = others.weights(r0 + moved @ delta)
        trial = np.linalg.lstsq(moved * weights[:, None], -r0 * weights, rcond=None)[0]
        lower = value(trial)
        if lower >= current - 1e-13 * max(1.0, abs(current)):
            current = min(current, lower)
            break
        delta, current = trial, lower
    return current
