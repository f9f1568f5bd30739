"""The posterior's parts without the solver: the GP surrogate against known functions (its held-out error against
the error measured on many points), emcee on a known Gaussian, and the whole route on a linear-Gaussian model
whose posterior mean and covariance are known in closed form."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import qmc

from biostudy.fitting import sampling, surrogate
from biostudy.fitting.objective import Objective
from biostudy.fitting.posterior import Options, posterior

LOW, HIGH = np.array([0.2, 0.1]), np.array([0.7, 0.9])


def smooth(u):
    u = np.atleast_2d(u)
    return np.stack([np.sin(4 * u[:, 0]) + 0.5 * np.cos(3 * u[:, 1]) + u[:, 0] * u[:, 1],
                     3.0 + 10 * u[:, 0] - 4 * u[:, 1] ** 2], axis=1)


def inside(count, seed):
    return LOW + (HIGH - LOW) * np.random.default_rng(seed).random((count, 2))


@pytest.mark.parametrize("noise", [0.0, 0.02])
def test_the_surrogate_learns_a_known_function_and_its_held_out_error_is_the_error_it_makes(noise):
    train = LOW + (HIGH - LOW) * qmc.LatinHypercube(d=2, rng=3).random(40)
    rng = np.random.default_rng(5)
    gp = surrogate.train(train, smooth(train) + noise * rng.standard_normal((40, 2)), LOW, HIGH)
    dense = inside(4000, 7)
    truth_error = np.sqrt(np.mean((gp.predict(dense)[0] - smooth(dense)) ** 2, axis=0))  # what it really makes
    scale = np.ptp(smooth(dense), axis=0)
    if noise == 0:
        assert np.all(truth_error < 3e-3 * scale)  # a smooth function of two variables from 40 points
    else:
        assert np.all(truth_error < noise)  # the mean averages the noise out: no worse than one draw
    # 20 held-out runs (noisy as the training ones): their RMS error estimates sqrt(truth² + noise²) to within
    # the sampling error of a mean of 20 squares (a factor 2 either way is > 3 of its standard deviations)
    held = inside(20, 11)
    measured = surrogate.held_out(gp, held, smooth(held) + noise * rng.standard_normal((20, 2)))
    expected = np.sqrt(truth_error**2 + noise**2)
    assert measured.count == 20
    assert np.all(measured.error > expected / 2) and np.all(measured.error < expected * 2), (measured.error,
                                                                                             expected)
    # the GP's own predicted spread is of the size of the error it makes (calibrated within a factor 3)
    assert np.all(measured.predicted > expected / 3) and np.all(measured.predicted < expected * 3)


def test_the_sampler_reproduces_a_known_gaussian_within_its_monte_carlo_error():
    mean = np.array([0.4, 0.55])
    covariance = np.array([[0.004, 0.003], [0.003, 0.0036]])  # correlation 0.79
    precision = np.linalg.inv(covariance)

    def log_probability(u):
        d = u - mean
        return -0.5 * np.einsum("ij,jk,ik->i", d, precision, d)

    start = mean + 0.01 * np.random.default_rng(0).standard_normal((16, 2))
    chains = sampling.sample(log_probability, start, 3000, seed=2)
    assert chains.converged and chains.verdicts(["a", "b"]) == []
    assert 0.2 < chains.acceptance < 0.8
    error = np.sqrt(np.diag(covariance) / chains.effective)  # Monte-Carlo standard error of the mean
    assert np.all(np.abs(chains.samples.mean(axis=0) - mean) < 4 * error)
    np.testing.assert_allclose(np.cov(chains.samples.T), covariance, rtol=0.2, atol=0.2 * 0.003)
    median, low, high = sampling.quantiles(chains.samples)
    np.testing.assert_allclose(high - low, 2 * 1.96 * np.sqrt(np.diag(covariance)), rtol=0.1)
    short = sampling.sample(log_probability, start, 60, seed=2)
    assert not short.converged and "have not converged" in " ".join(short.verdicts(["a", "b"]))


T = np.linspace(0.1, 1.0, 8)
SIGMA = np.full(8, 0.05)
BASIS = np.stack([2 * T, 3 * T**2], axis=1)  # model = 1 + BASIS @ u


def test_the_posterior_of_a_linear_gaussian_model_is_its_closed_form():
    data = 1 + BASIS @ np.array([0.3, 0.6]) + SIGMA * np.random.default_rng(1).normal(size=8)
    weighted = BASIS / SIGMA[:, None]
    exact = np.linalg.lstsq(weighted, (data - 1) / SIGMA, rcond=None)[0]
    covariance = np.linalg.inv(weighted.T @ weighted)  # flat prior, far from the bounds: the posterior exactly
    calls = []

    def evaluate(points):
        calls.append(len(points))
        return [(1 + BASIS @ p - data) / SIGMA for p in points]

    options = Options(design=12, held_out=4, walkers=16, steps=2500, box=6.0, seed=3)
    se = np.sqrt(np.diag(covariance))
    found = posterior(Objective(evaluate, 8, np.zeros(8), ("a", "b")), exact, se, options)
    assert calls == [12, 6, 4] and found.trained_on == 18 and found.held.count == 4  # design, refinement, held out
    assert np.all(found.held.error < 1e-3)  # a linear model: the trend is exact
    chains = found.chains
    assert chains.converged and found.verdicts == [], found.verdicts
    assert np.all(np.abs(chains.samples.mean(axis=0) - exact) < 4 * se / np.sqrt(chains.effective))
    np.testing.assert_allclose(np.cov(chains.samples.T), covariance, rtol=0.2, atol=0.2 * abs(covariance[0, 1]))
    np.testing.assert_allclose(found.low, np.maximum(exact - 6 * se, 0.0))
    # the band of the model: 1.96 sigma_i sqrt(B_i C B_i^T) each side, in residual units
    width = 2 * 1.96 * np.sqrt(np.einsum("ij,jk,ik->i", weighted, covariance, weighted))
    np.testing.assert_allclose(found.band[1] - found.band[0], width, rtol=0.15)


def test_failed_runs_are_left_out_of_the_training_and_the_held_out_error_and_counted():
    data = 1 + BASIS @ np.array([0.3, 0.6]) + SIGMA * np.random.default_rng(1).normal(size=8)
    weighted = BASIS / SIGMA[:, None]
    exact = np.linalg.lstsq(weighted, (data - 1) / SIGMA, rcond=None)[0]
    se = np.sqrt(np.diag(np.linalg.inv(weighted.T @ weighted)))
    asked = []

    def evaluate(points):  # every third simulation 'fails'
        asked.extend(points)
        return [None if (len(asked) - len(points) + i) % 3 == 0 else (1 + BASIS @ p - data) / SIGMA
                for i, p in enumerate(points)]

    found = posterior(Objective(evaluate, 8, np.zeros(8), ("a", "b")), exact, se,
                      Options(design=12, held_out=6, steps=1000, seed=3))
    failed = sum(i % 3 == 0 for i in range(len(asked)))
    assert found.failed == failed and len(asked) == 12 + 6 + 6
    assert found.trained_on == found.designed == 12 + 6 - sum(i % 3 == 0 for i in range(18))
    assert found.held.count == 6 - sum(i % 3 == 0 for i in range(18, 24))
    assert np.all(np.isfinite(found.chains.samples)) and np.all(found.held.error < 1e-3)


def test_a_parameter_the_data_do_not_see_is_said_to_reach_its_bounds_and_its_interval_to_be_the_priors():
    data = 1 + 2 * T * 0.4 + SIGMA * np.random.default_rng(2).normal(size=8)  # the model ignores u[1]
    weighted = (2 * T / SIGMA)[:, None]
    exact = float(np.linalg.lstsq(weighted, (data - 1) / SIGMA, rcond=None)[0][0])
    se = float(np.sqrt(np.linalg.inv(weighted.T @ weighted)[0, 0]))

    def evaluate(points):
        return [(1 + 2 * T * p[0] - data) / SIGMA for p in points]

    options = Options(design=12, held_out=4, walkers=16, steps=1500, box=6.0, seed=3)
    found = posterior(Objective(evaluate, 8, np.zeros(8), ("a", "b")), np.array([exact, 0.5]), np.array([se, np.inf]),
                      options)
    said = " ".join(found.verdicts)
    assert "the posterior of b reaches its lower bound" in said and "the posterior of b reaches its upper bound" in said
    assert "the data do not bound b on that side" in said and "posterior of a" not in said, found.verdicts
    _, low, high = sampling.quantiles(found.chains.samples)
    assert low[1] < 0.1 and high[1] > 0.9  # flat over the prior: the 95 % interval is most of the range
