"""A Gaussian-process surrogate of the weighted residuals: one small GP per residual, over a box of the unit cube.

Each residual r_i(u) = (model_i(u) - measurement_i) / sigma_i is modelled as a linear trend in u plus a
zero-mean Gaussian process with a squared-exponential kernel of its own length scale per coordinate (ARD),
an amplitude and a nugget (the solver's small jumps: a simulation is not a perfectly smooth function of its
parameters, docs/calibration.md), all by maximising the marginal likelihood (Rasmussen & Williams 2006, eq.
2.30, its gradient eq. 5.9) from six starts.  The coordinates are those of the training box scaled to [0, 1],
the residual left by the trend scaled to unit variance, so one set of hyper-parameter bounds serves every
output.  `predict` gives the mean and the variance of what a simulation would give (the nugget included);
`held_out` measures the surrogate's error against simulations it was not trained on, which is what the
likelihood adds to sigma².  Its matrices are small (~100²): one BLAS thread (`threadpool_limits`), as several
made each likelihood 7-20 times slower on this 2-core machine under load (measured: 0.7 ms against 5.7-15.7).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

# bounds of log(length scale) (box coordinates in [0, 1]), log(amplitude), log(nugget) (unit-variance outputs)
LENGTH = (np.log(0.03), np.log(30.0))
AMPLITUDE = (np.log(1e-2), np.log(1e2))
NUGGET = (np.log(1e-5), np.log(1.0))
JITTER = 1e-10
# the marginal likelihood has several local optima (a smoother fit with more nugget, a rougher one with less):
# L-BFGS from each of these (length scale, nugget), the best kept
STARTS = [(length, nugget) for length in (0.2, 0.5, 1.5) for nugget in (1e-2, 1e-1)]


def _kernel(a: np.ndarray, b: np.ndarray, length: np.ndarray, amplitude: float) -> np.ndarray:
    d = (a[:, None, :] - b[None, :, :]) / length
    return amplitude**2 * np.exp(-0.5 * np.sum(d * d, axis=-1))


@dataclass(frozen=True)
class Output:
    """One residual's GP: the trend, the scale of what the trend leaves, the hyper-parameters, the weights."""

    trend: np.ndarray  # [constant, slopes...] in box coordinates
    scale: float
    length: np.ndarray
    amplitude: float
    nugget: float
    weights: np.ndarray  # K^-1 (z - 0), z the scaled remainder at the training points
    factor: tuple  # Cholesky factor of K (nugget included)


@dataclass(frozen=True, eq=False)
class Surrogate:
    """GPs of every residual over a box [low, high] of the unit cube, trained on `points`."""

    low: np.ndarray
    high: np.ndarray
    points: np.ndarray  # training points in box coordinates
    outputs: list[Output]

    def _box(self, u: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(u) - self.low) / (self.high - self.low)

    def predict(self, u: np.ndarray, variance: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Mean and variance (points x residuals) of the residuals a simulation at each point would give (the
        variance only when asked: None otherwise)."""
        x = self._box(u)
        trend, scale, length, amplitude, nugget, weights, root = self._stacked
        d = (x[None, :, None, :] - self.points[None, None, :, :]) / length[:, None, None, :]
        cross = amplitude[:, None, None] ** 2 * np.exp(-0.5 * np.sum(d * d, axis=-1))  # residuals x points x train
        design = np.hstack([np.ones((len(x), 1)), x])
        mean = design @ trend.T + scale * np.einsum("ipm,im->pi", cross, weights)
        if not variance:
            return mean, None
        # |L^-1 k*|², L the Cholesky factor of K: an explicit inverse of a nearly singular K would lose the digits
        latent = amplitude[:, None] ** 2 - np.sum(np.einsum("imn,ipn->ipm", root, cross) ** 2, axis=-1)
        return mean, (scale[:, None] ** 2 * (np.maximum(latent, 0.0) + nugget[:, None] ** 2)).T

    @functools.cached_property
    def _stacked(self):
        """Every output's parameters as arrays over the residuals (one vectorised prediction for all)."""
        outs = self.outputs
        return (np.array([o.trend for o in outs]), np.array([o.scale for o in outs]),
                np.array([o.length for o in outs]), np.array([o.amplitude for o in outs]),
                np.array([o.nugget for o in outs]), np.array([o.weights for o in outs]),
                np.array([solve_triangular(np.tril(o.factor[0]), np.eye(len(self.points)), lower=True) for o in outs]))


def _negative_log_likelihood(theta: np.ndarray, x: np.ndarray, z: np.ndarray) -> tuple[float, np.ndarray]:
    """-log p(z | theta) up to a constant, and its gradient (R&W eq. 5.9: 1/2 tr((K^-1 - a a^T) dK/dtheta))."""
    k = x.shape[1]
    length, amplitude, nugget = np.exp(theta[:k]), np.exp(theta[k]), np.exp(theta[k + 1])
    scaled = (x[:, None, :] - x[None, :, :]) ** 2 / length**2  # m x m x k
    kernel = amplitude**2 * np.exp(-0.5 * np.sum(scaled, axis=-1))
    gram = kernel + (nugget**2 + JITTER) * np.eye(len(x))
    try:
        factor = cho_factor(gram, lower=True)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(theta)
    alpha = cho_solve(factor, z)
    value = float(0.5 * z @ alpha + np.sum(np.log(np.diag(factor[0]))))
    w = cho_solve(factor, np.eye(len(x))) - np.outer(alpha, alpha)
    gradient = np.empty_like(theta)
    gradient[:k] = 0.5 * np.einsum("ij,ij,ijd->d", w, kernel, scaled)
    gradient[k] = np.sum(w * kernel)
    gradient[k + 1] = nugget**2 * np.trace(w)
    return value, gradient


def _output(x: np.ndarray, y: np.ndarray) -> Output:
    design = np.hstack([np.ones((len(x), 1)), x])
    trend = np.linalg.lstsq(design, y, rcond=None)[0]
    remainder = y - design @ trend
    scale = float(np.std(remainder))
    k = x.shape[1]
    if scale <= 1e-12 * max(1.0, float(np.max(np.abs(y)))):  # the trend is exact (a linear model)
        scale = 1.0
    z = remainder / scale
    bounds = [LENGTH] * k + [AMPLITUDE, NUGGET]
    best = None
    for length, nugget in STARTS:
        start = np.array([np.log(length)] * k + [0.0, np.log(nugget)])
        found = minimize(_negative_log_likelihood, start, args=(x, z), jac=True, method="L-BFGS-B", bounds=bounds)
        if best is None or found.fun < best.fun:
            best = found
    length, amplitude, nugget = np.exp(best.x[:k]), float(np.exp(best.x[k])), float(np.exp(best.x[k + 1]))
    gram = _kernel(x, x, length, amplitude) + (nugget**2 + JITTER) * np.eye(len(x))
    factor = cho_factor(gram, lower=True)
    return Output(trend, scale, length, amplitude, nugget, cho_solve(factor, z), factor)


def train(points: np.ndarray, residuals: np.ndarray, low: np.ndarray, high: np.ndarray) -> Surrogate:
    """GPs of every column of `residuals` (training points x residuals) at `points` (unit cube, inside the box
    [low, high]); needs more points than coordinates + 1."""
    points, residuals = np.atleast_2d(points), np.atleast_2d(residuals)
    if len(points) < points.shape[1] + 2:
        raise ValueError(f"a surrogate of {points.shape[1]} parameters needs at least {points.shape[1] + 2} "
                         f"training runs (got {len(points)})")
    low, high = np.array(low, float), np.array(high, float)  # copies: the caller widens its box later
    x = (points - low) / (high - low)
    with threadpool_limits(1, user_api="blas"):
        return Surrogate(low, high, x, [_output(x, residuals[:, i]) for i in range(residuals.shape[1])])


@dataclass(frozen=True)
class HeldOut:
    """The surrogate against simulations it was not trained on, per residual (units of sigma)."""

    error: np.ndarray  # root mean square of (predicted - simulated)
    predicted: np.ndarray  # root mean predicted variance there: what the GP itself expected
    count: int


def held_out(surrogate: Surrogate, points: np.ndarray, residuals: np.ndarray) -> HeldOut:
    """The root-mean-square error of the surrogate's mean at held-out points, per residual."""
    mean, variance = surrogate.predict(points)
    error = np.sqrt(np.mean((mean - np.atleast_2d(residuals)) ** 2, axis=0))
    return HeldOut(error, np.sqrt(np.mean(variance, axis=0)), len(mean))
