"""The fitting maths (biostudy.fitting) against exact answers: a model linear in its parameters, where weighted
least squares, its covariance and its profile intervals are known in closed form; a parameter the residuals do
not depend on; a failed evaluation; rounds that hold one request of every live fit, and no threads."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import biostudy.fitting
from biostudy.fitting import rounds
from biostudy.fitting.estimate import least_squares
from biostudy.fitting.least_squares import PENALTY
from biostudy.fitting.objective import Objective
from biostudy.fitting.profiles import THRESHOLD
from biostudy.fitting.rounds import Ask, Stopped

T = np.linspace(0.1, 1.0, 8)
SIGMA = np.full(8, 0.05)
BASIS = np.stack([2 * T, 3 * T**2], axis=1)  # model = 1 + BASIS @ u: linear in the unit-cube coordinates u


def linear_data(seed=1, truth=(0.3, 0.6)):
    return 1 + BASIS @ np.array(truth) + SIGMA * np.random.default_rng(seed).normal(size=8)


def residuals_of(data, model=lambda u: 1 + BASIS @ u):
    return lambda points: [(model(np.asarray(p)) - data) / SIGMA for p in points]


def objective(evaluate, noise=1e-9, workers=1):
    return Objective(evaluate, 8, np.full(8, noise), ("a", "b"), workers)


def test_a_linear_model_gives_the_closed_form_estimate_covariance_and_intervals():
    data = linear_data()
    weighted = BASIS / SIGMA[:, None]
    exact = np.linalg.lstsq(weighted, (data - 1) / SIGMA, rcond=None)[0]
    covariance = np.linalg.inv(weighted.T @ weighted)
    starts = np.array([[0.05, 0.95], [0.95, 0.05]])
    found = least_squares(starts, objective(residuals_of(data)))
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
    found = least_squares(np.array([[0.2, 0.3]]), objective(residuals_of(data, model), 1e-12))
    first, second = found.profiles
    assert first.identifiable and not second.identifiable
    assert second.open_below and second.open_above and (second.lower, second.upper) == (0.0, 1.0)
    assert np.ptp(second.chi2) < 1e-6


def test_after_a_refit_every_profile_and_interval_comes_from_the_new_optimum():
    """Issue 39.1: a start on a flat stretch of chi² (the model does not move while a <= 0.4) ends at once; a's
    profile steps off the stretch and finds chi² far below it, so the fit is repeated from there.  The profiles
    must then be centred on that optimum: b, which the data determine once a > 0.4, is identifiable and its
    interval holds the truth; read from branches around the abandoned start it stayed open from bound to bound."""
    truth = np.array([0.7, 0.5])
    model = lambda u: 1 + 2 * max(u[0] - 0.4, 0.0) * (2 * T + 3 * T**2 * u[1])  # noqa: E731
    data = model(truth) + SIGMA * np.random.default_rng(4).normal(size=8)
    found = least_squares(np.array([[0.2, 0.3]]), objective(residuals_of(data, model)))
    assert found.starts_chi2 is not None and found.starts_chi2 > found.best.chi2 + 100  # the refit happened
    for j, profile in enumerate(found.profiles):
        assert found.best.x[j] in profile.u  # centred on the estimate reported
        assert profile.chi2.min() == pytest.approx(found.best.chi2, abs=0.1)  # nothing below it (`REFIT`)
        assert profile.identifiable and profile.lower < truth[j] < profile.upper
    assert found.minimum == pytest.approx(found.best.chi2, abs=0.1)


def test_a_failed_evaluation_is_a_penalty_and_the_fit_stops_at_its_edge():
    data = linear_data(3, truth=(0.9, 0.6))
    good = residuals_of(data)

    def evaluate(points):  # beyond u0 = 0.8 every simulation 'fails', the optimum among them
        return [None if p[0] > 0.8 else r for p, r in zip(points, good(points))]

    found = least_squares(np.array([[0.4, 0.5]]), objective(evaluate), with_profiles=False)
    assert found.fits[0].failed >= 1  # it tried, was refused, and went on
    assert found.best.x[0] <= 0.8 and found.best.chi2 < PENALTY  # the best point that ran
    edge = least_squares(np.array([[0.79, 0.6]]), objective(good), with_profiles=False).best
    assert found.best.chi2 < chi2_at(good, np.array([0.4, 0.5]))
    assert edge.x[0] > 0.8  # without the failures it would have gone there


def chi2_at(residuals, point):
    return float(np.sum(residuals([point])[0] ** 2))


def asking(asks):
    """A fit that asks for one point at a time, `asks` times, and returns the sum of its answers."""
    total = 0.0
    for i in range(asks):
        total += sum((yield Ask([np.array([i, 1.0])])))
    return total


def test_rounds_hold_one_request_of_every_live_fit():
    seen = []

    def evaluate(points):
        seen.append(len(points))
        return [float(np.sum(p)) for p in points]

    outcome = rounds.run({"a": asking(3), "b": asking(5), "c": asking(1)}, evaluate)
    assert seen == [3, 2, 2, 1, 1]  # while all three live, then two, then one
    assert outcome == {"a": 6.0, "b": 15.0, "c": 1.0}


def test_a_stopped_fit_ends_where_it_waits_and_the_others_go_on():
    fits = {"a": asking(3), "b": asking(3)}
    outcome = rounds.run(fits, lambda points: [1.0] * len(points),
                         lambda waiting: {"b"} if len(waiting) == 2 else set())
    assert outcome["a"] == 3.0 and isinstance(outcome["b"], Stopped)


def test_soon_points_join_a_round_only_when_workers_would_wait():
    def fit():
        answers = yield Ask([np.zeros(2)], [np.ones(2), np.full(2, 2.0)])
        return len(answers)

    for workers, taken in ((1, 1), (2, 2), (3, 3)):  # 2: the point and the first soon one, no worker waits
        assert rounds.run({"f": fit()}, lambda points: [0.0] * len(points), workers=workers)["f"] == taken
    seen = []

    def evaluate(points):
        seen.append(len(points))
        return [0.0] * len(points)

    fits = {name: fit() for name in "abc"}  # three fits on 2 workers: the second wave's idle worker takes one
    assert rounds.run(fits, evaluate, workers=2) == {"a": 2, "b": 1, "c": 1} and seen == [4]


@pytest.mark.parametrize("workers", [2, 3, 16])
def test_more_workers_do_not_change_the_path(workers):
    data = linear_data(4)
    serial = least_squares(np.array([[0.2, 0.7]]), objective(residuals_of(data)))
    wide = least_squares(np.array([[0.2, 0.7]]), objective(residuals_of(data), workers=workers))
    np.testing.assert_array_equal(serial.best.x, wide.best.x)
    for a, b in zip(serial.profiles, wide.profiles):
        np.testing.assert_array_equal(a.u, b.u)
        np.testing.assert_array_equal(a.chi2, b.chi2)


def test_an_error_in_a_round_ends_every_fit():
    def evaluate(points):
        raise KeyboardInterrupt

    fits = {"a": asking(2), "b": asking(2)}
    with pytest.raises(KeyboardInterrupt):
        rounds.run(fits, evaluate)
    assert all(fit.gi_frame is None for fit in fits.values())  # closed, nothing left waiting


def test_the_fits_run_without_threads():
    package = Path(biostudy.fitting.__file__).parent
    assert not [path.name for path in package.glob("*.py") if "threading" in path.read_text(encoding="utf-8")]
