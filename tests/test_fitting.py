"""The fitting maths (biostudy.fitting) against exact answers: a model linear in its parameters, where weighted
least squares, its covariance and its profile intervals are known in closed form; a parameter the residuals do
not depend on; a failed evaluation; rounds that are the same whatever the threads' timing."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from biostudy.fitting import rounds
from biostudy.fitting.estimate import least_squares
from biostudy.fitting.least_squares import PENALTY
from biostudy.fitting.profiles import THRESHOLD

T = np.linspace(0.1, 1.0, 8)
SIGMA = np.full(8, 0.05)
BASIS = np.stack([2 * T, 3 * T**2], axis=1)  # model = 1 + BASIS @ u: linear in the unit-cube coordinates u


def linear_data(seed=1, truth=(0.3, 0.6)):
    return 1 + BASIS @ np.array(truth) + SIGMA * np.random.default_rng(seed).normal(size=8)


def residuals_of(data, model=lambda u: 1 + BASIS @ u):
    return lambda points: [(model(np.asarray(p)) - data) / SIGMA for p in points]


def test_a_linear_model_gives_the_closed_form_estimate_covariance_and_intervals():
    data = linear_data()
    weighted = BASIS / SIGMA[:, None]
    exact = np.linalg.lstsq(weighted, (data - 1) / SIGMA, rcond=None)[0]
    covariance = np.linalg.inv(weighted.T @ weighted)
    starts = np.array([[0.05, 0.95], [0.95, 0.05]])
    found = least_squares(starts, 8, np.full(8, 1e-9), residuals_of(data))
    np.testing.assert_allclose(found.best.x, exact, atol=0.01 * np.sqrt(np.diag(covariance)).max() * 10)
    np.testing.assert_allclose(found.local.covariance, covariance, rtol=1e-4)  # forward differences of a line
    np.testing.assert_allclose(found.local.correlation[0, 1], covariance[0, 1] / np.sqrt(covariance[0, 0] *
                                                                                         covariance[1, 1]), rtol=1e-4)
    # a quadratic chi²: the profile interval is estimate ± sqrt(3.84) standard errors (linear interpolation of the
    # crossing between points about one standard error apart: within 2 % of a standard error)
    for j, profile in enumerate(found.profiles):
        error = np.sqrt(covariance[j, j])
        assert profile.identifiable
        assert profile.lower == pytest.approx(exact[j] - np.sqrt(THRESHOLD) * error, abs=0.02 * error)
        assert profile.upper == pytest.approx(exact[j] + np.sqrt(THRESHOLD) * error, abs=0.02 * error)
    assert sum(f is None or f.stopped for f in found.fits) <= 1


def test_a_parameter_the_data_cannot_see_is_not_identifiable_and_its_interval_reaches_the_bounds():
    data = linear_data(2, truth=(0.3, 0.0))
    model = lambda u: 1 + BASIS[:, 0] * u[0] + 1e-9 * u[1]  # noqa: E731 -- u[1] moves the model by nothing
    found = least_squares(np.array([[0.2, 0.3]]), 8, np.full(8, 1e-12), residuals_of(data, model))
    first, second = found.profiles
    assert first.identifiable and not second.identifiable
    assert second.open_below and second.open_above and (second.lower, second.upper) == (0.0, 1.0)
    assert np.ptp(second.chi2) < 1e-6


def test_a_failed_evaluation_is_a_penalty_and_the_fit_stops_at_its_edge():
    data = linear_data(3, truth=(0.9, 0.6))
    good = residuals_of(data)

    def evaluate(points):  # beyond u0 = 0.8 every simulation 'fails', the optimum among them
        return [None if p[0] > 0.8 else r for p, r in zip(points, good(points))]

    found = least_squares(np.array([[0.4, 0.5]]), 8, np.full(8, 1e-9), evaluate, with_profiles=False)
    assert found.fits[0].failed >= 1  # it tried, was refused, and went on
    assert found.best.x[0] <= 0.8 and found.best.chi2 < PENALTY  # the best point that ran
    edge = least_squares(np.array([[0.79, 0.6]]), 8, np.full(8, 1e-9), good, with_profiles=False).best
    assert found.best.chi2 < chi2_at(good, np.array([0.4, 0.5]))
    assert edge.x[0] > 0.8  # without the failures it would have gone there


def chi2_at(residuals, point):
    return float(np.sum(residuals([point])[0] ** 2))


def test_rounds_hold_one_request_of_every_live_fit_whatever_the_timing():
    seen = []

    def evaluate(points):
        seen.append(len(points))
        return [float(np.sum(p)) for p in points]

    def task(delay, asks):
        def run(ask):
            total = 0.0
            for i in range(asks):
                time.sleep(delay * (i % 2))  # the threads arrive in different orders from round to round
                total += sum(ask([np.array([i, 1.0])]))
            return total
        return run

    outcome = rounds.run({"a": task(0.01, 3), "b": task(0.0, 5), "c": task(0.02, 1)}, evaluate)
    assert seen == [3, 2, 2, 1, 1]  # while all three live, then two, then one
    assert outcome == {"a": 6.0, "b": 15.0, "c": 1.0}
    assert threading.active_count() >= 1


def test_an_error_in_a_round_ends_every_fit():
    def evaluate(points):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        rounds.run({"a": lambda ask: ask([np.zeros(1)]), "b": lambda ask: ask([np.ones(1)])}, evaluate)
