"""σ named in `noiseParameters` and estimated with the parameters (issue 26.6), against theory: a model linear in
its parameters, where maximum likelihood with an unknown σ is ordinary least squares with σ̂² = SS/n, its profile
intervals and σ's own interval have closed forms, and σ̂² scatters as 2σ⁴/n; a brute-force profile of the exact
likelihood where groups and given σs mix; the table's refusals, calibration.nc and its table, and one calibration
of the tiny colony end to end."""
from __future__ import annotations

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from scipy import stats
from scipy.optimize import brentq, minimize
from test_calibration_hostile import COST, calibration, invoke, one_line, table

from biostudy.fitting.estimate import least_squares
from biostudy.fitting.least_squares import PENALTY
from biostudy.fitting.likelihood import THRESHOLD, Likelihood, chi2, coverage
from biostudy.fitting.objective import Objective

STARTS = np.array([[0.05, 0.95], [0.95, 0.05]])


def design(n: int) -> np.ndarray:
    t = np.linspace(0.1, 1.0, n)
    return np.stack([2 * t, 3 * t**2], axis=1)  # model = 1 + X @ u: linear in the unit-cube coordinates u


def objective(x: np.ndarray, data: np.ndarray, divisor: np.ndarray, likelihood: Likelihood, fail=None):
    def evaluate(points):
        return [None if fail is not None and fail(p) else (1 + x @ np.asarray(p) - data) / divisor for p in points]

    return Objective(evaluate, len(data), np.full(len(data), 1e-9), ("a", "b"), likelihood=likelihood)


def sigma_ends(n: int, sigma: float) -> tuple[float, float]:
    """σ's 95 % profile interval of n rows sharing it, all alone: n (σ̂²/σ² + log(σ²/σ̂²) - 1) = 3.84."""
    rise = lambda v: n * (1 / v + math.log(v) - 1) - THRESHOLD  # noqa: E731 -- v = σ² / σ̂²
    return sigma * math.sqrt(brentq(rise, 1e-6, 1.0)), sigma * math.sqrt(brentq(rise, 1.0, 1e6))


def test_one_unknown_sigma_is_ordinary_least_squares_with_its_closed_form_intervals():
    n = 12
    x = design(n)
    data = 1 + x @ np.array([0.3, 0.6]) + 0.05 * np.random.default_rng(1).normal(size=n)
    scale = 3.0  # the residuals' fixed scale: nothing reported depends on it
    found = least_squares(STARTS, objective(x, data, np.full(n, scale), Likelihood((np.arange(n),), (scale,))))
    ols = np.linalg.lstsq(x, data - 1, rcond=None)[0]
    inverse = np.linalg.inv(x.T @ x)
    ss = float(np.sum((1 + x @ ols - data) ** 2))
    variance = ss / n
    errors = np.sqrt(variance * np.diag(inverse))
    # the fit ends within its tolerance (0.01 of -2 log L): a tenth of a standard error of ordinary least squares
    np.testing.assert_allclose(found.best.x, ols, atol=0.1 * errors.min())
    sigma = found.sigmas[0]
    at_estimate = float(np.sum((1 + x @ found.best.x - data) ** 2)) / n
    assert sigma.estimate**2 == pytest.approx(at_estimate, rel=1e-12)  # σ̂² = SS/n, exactly, where it ended
    assert sigma.estimate**2 == pytest.approx(variance, rel=0.01 / n)
    assert found.best.chi2 == pytest.approx(n * (1 + math.log(at_estimate)), rel=1e-12)
    # covariance σ̂² (XᵀX)⁻¹ (maximum likelihood's σ̂)
    np.testing.assert_allclose(found.local.covariance, variance * inverse, rtol=1e-4)
    # the profile of u_j, σ re-estimated at every point: n log(SS_j / SS) = 3.84 at
    # u_j = û_j ± σ̂ sqrt(c_jj) sqrt(n (exp(3.84 / n) - 1))  (the t statistic's exact profile)
    for j, profile in enumerate(found.profiles):
        half = errors[j] * math.sqrt(n * (math.exp(THRESHOLD / n) - 1))
        assert profile.identifiable
        assert profile.lower == pytest.approx(ols[j] - half, abs=0.02 * errors[j])
        assert profile.upper == pytest.approx(ols[j] + half, abs=0.02 * errors[j])
    lower, upper = sigma_ends(n, sigma.estimate)
    assert (sigma.lower, sigma.upper) == pytest.approx((lower, upper), rel=1e-5)
    assert sigma.rows == n


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_groups_recover_their_own_sigma_within_its_sampling_error(seed):
    n = 200  # per group
    x = np.vstack([design(n), design(n)])
    truth = np.array([0.05] * n + [0.5] * n)
    data = 1 + x @ np.array([0.3, 0.6]) + truth * np.random.default_rng(seed).normal(size=2 * n)
    groups = (np.arange(n), np.arange(n, 2 * n))
    found = least_squares(STARTS, objective(x, data, np.ones(2 * n), Likelihood(groups, (1.0, 1.0))),
                          with_profiles=False)
    for sigma, true in zip(found.sigmas, (0.05, 0.5)):
        # var(σ̂²) = 2σ⁴/n; E σ̂² = σ² (1 - 2 / 2n) at most 0.5 % low: within 3.5 standard deviations
        assert abs(sigma.estimate**2 / true**2 - 1) < 3.5 * math.sqrt(2 / n)
    # the estimate is the weighted least squares with the σ̂s as weights (the likelihood's stationary point)
    weights = np.concatenate([np.full(n, 1 / found.sigmas[0].estimate), np.full(n, 1 / found.sigmas[1].estimate)])
    weighted = np.linalg.lstsq(x * weights[:, None], (data - 1) * weights, rcond=None)[0]
    errors = np.sqrt(np.diag(found.local.covariance))
    np.testing.assert_allclose(found.best.x, weighted, atol=0.1 * errors.min())


def exact_minus_two_log_l(u, log_sigmas, x, data, given, sigma_given, groups):
    """-2 log L of the linear model, written out (the constant n log 2π and Σ log σ_i² of given rows left out)."""
    r = 1 + x @ u - data
    total = float(np.sum((r[given] / sigma_given) ** 2))
    for rows, log_sigma in zip(groups, log_sigmas):
        total += float(np.sum(r[rows] ** 2)) / math.exp(2 * log_sigma) + 2 * len(rows) * log_sigma
    return total


def test_a_sigma_interval_is_its_profile_with_parameters_and_other_sigmas_re_optimised():
    n = 10
    x = np.vstack([design(n)] * 3)
    rng = np.random.default_rng(4)
    data = 1 + x @ np.array([0.4, 0.5]) + np.repeat([0.02, 0.1, 0.3], n) * rng.normal(size=3 * n)
    given, groups = np.arange(n), (np.arange(n, 2 * n), np.arange(2 * n, 3 * n))
    sigma_given = 0.02
    divisor = np.concatenate([np.full(n, sigma_given), np.full(2 * n, 1.0)])
    found = least_squares(STARTS, objective(x, data, divisor, Likelihood(groups, (1.0, 1.0))), with_profiles=False)
    best = minimize(lambda p: exact_minus_two_log_l(p[:2], p[2:], x, data, given, sigma_given, groups),
                    np.array([0.5, 0.5, -2.0, -1.0]), method="Nelder-Mead",
                    options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 20000}).fun
    assert found.best.chi2 == pytest.approx(best, abs=0.01)  # F is -2 log L with σ profiled out

    def profile(g: int, sigma: float) -> float:
        """-2 log L at σ_g = sigma, minimised over u and the other σ by brute force."""
        def held(p):
            log_sigmas = [math.log(sigma), p[2]] if g == 0 else [p[2], math.log(sigma)]
            return exact_minus_two_log_l(p[:2], log_sigmas, x, data, given, sigma_given, groups)
        return minimize(held, np.array([0.4, 0.5, -1.5]), method="Nelder-Mead",
                        options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 20000}).fun

    for g, sigma in enumerate(found.sigmas):
        for end in (sigma.lower, sigma.upper):
            assert profile(g, end) - best == pytest.approx(THRESHOLD, abs=0.02)


def test_a_failed_simulation_stays_a_penalty_when_sigma_is_estimated():
    n = 12
    x = design(n)
    data = 1 + x @ np.array([0.9, 0.6]) + 0.05 * np.random.default_rng(3).normal(size=n)
    scale = 1e-4  # residuals of thousands of scales where the fit starts: a failed run's 1e3 must not look better
    likelihood = Likelihood((np.arange(n),), (scale,))
    found = least_squares(np.array([[0.4, 0.5]]), objective(x, data, np.full(n, scale), likelihood,
                                                            lambda p: p[0] > 0.8), with_profiles=False)
    assert found.fits[0].failed >= 1 and found.best.x[0] <= 0.8  # refused beyond the edge, not taken for a fit
    assert likelihood.value(np.full(n, PENALTY)) == n * PENALTY**2


def test_without_noise_parameters_the_objective_is_chi2_and_the_residuals_are_untouched():
    r, jacobian = np.array([0.3, -1.2, 2.5]), np.ones((3, 2))
    plain = Likelihood()
    assert plain.value(r) == chi2(r) == float(np.sum(r**2))
    weighted = plain.weighted(r, jacobian)
    assert weighted[0] is r and weighted[1] is jacobian  # the same arrays: the same bits downstream


@pytest.mark.parametrize("n, k", [(4, 2), (6, 2), (12, 3), (40, 2)])
def test_few_rows_give_short_intervals_as_the_t_and_chi2_distributions_say(n, k):
    parameter, sigma = coverage(n, k)
    # u's profile n log(1 + t² / (n - k)) <= 3.84, t² ~ F(1, n - k)
    assert parameter == pytest.approx(stats.f.cdf((n - k) * math.expm1(THRESHOLD / n), 1, n - k), rel=1e-9)
    # σ's interval is σ̂ (a, b) (`sigma_ends`), n σ̂² / σ² ~ chi²(n - k): it holds σ where n / b² <= chi² <= n / a²
    a, b = sigma_ends(n, 1.0)
    assert sigma == pytest.approx(stats.chi2.cdf(n / a**2, n - k) - stats.chi2.cdf(n / b**2, n - k), rel=1e-6)
    assert sigma < parameter < 0.95


# ---- the table, the plan, calibration.nc ---------------------------------------------------------------------------

def named(*rows: tuple[str, str, float, float, object]) -> str:
    return table(*rows)


GROUPED = named(("biomass", "", 0.02, 1.0, "sigma_b"), ("biomass", "", 0.05, 1.3, "sigma_b"),
                ("biomass", "", 0.08, 1.7, "sigma_b"), ("max_thickness", "", 0.05, 2.0, 0.1),
                ("max_thickness", "", 0.08, 2.9, 0.1))
ESTIMATE = '[estimate]\nr = [20.0, 250.0]\n[method]\nstarts = 1\n'


def test_a_named_sigma_is_grouped_by_its_name(tmp_path):
    from biostudy.calibration.noise import divisors
    from biostudy.calibration.problem import load_calibration

    plan = load_calibration(calibration(tmp_path, GROUPED, ESTIMATE))
    (noise,) = plan.noise
    assert (noise.name, noise.rows, noise.units) == ("sigma_b", (0, 1, 2), "um")
    assert noise.scale == pytest.approx(math.sqrt((1.0 + 1.3**2 + 1.7**2) / 3))
    assert [m.noise for m in plan.measurements] == ["sigma_b"] * 3 + ["", ""]
    np.testing.assert_allclose(divisors(plan.measurements, plan.noise), [noise.scale] * 3 + [0.1, 0.1])


@pytest.mark.parametrize("rows, body, expected", [
    (named(("biomass", "", 0.05, 1.0, "s"), ("biomass", "", 0.08, 1.2, 0.1)), ESTIMATE,
     "t.tsv: line 2: noiseParameters: s names the σ of this row alone: σ cannot be estimated from one row"),
    (named(("biomass", "", 0.05, 1.0, "s"), ("coverage", "", 0.08, 0.3, "s")), ESTIMATE,
     "t.tsv: line 3: noiseParameters: s is the σ of rows in different units: biomass in um (line 2) and coverage "
     "in 1: one σ is one quantity"),
    (named(("biomass", "", 0.05, 1.0, "r"), ("biomass", "", 0.08, 1.2, "r")), ESTIMATE,
     "t.tsv: line 2: noiseParameters: r is an estimated parameter of the scene, not a noise parameter"),
    (GROUPED, '[estimate]\nr = [20.0, 250.0]\n[method]\nname = "posterior"\n',
     "c.toml: method.name: \"posterior\" takes σ as given, and t.tsv names σ to estimate (sigma_b, line 2): give σ "
     "as numbers, or use name = \"least-squares\""),
    (named(("biomass", "", 0.05, 1.0, "2sigma"), ("biomass", "", 0.08, 1.2, 0.1)), ESTIMATE,
     "t.tsv: line 2: noiseParameters: neither a number nor a noise parameter's name (got '2sigma'"),
    (named(("biomass", "", 0.05, 1.0, "nan"), ("biomass", "", 0.08, 1.2, 0.1)), ESTIMATE,
     "t.tsv: line 2: noiseParameters: must be a finite number (got 'nan')"),
])
def test_noise_parameters_that_cannot_be_estimated_are_one_line_before_anything_runs(tmp_path, rows, body, expected):
    path = calibration(tmp_path, rows, body)
    one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"), expected)
    assert not (tmp_path / "out").exists()


def fitted_with_noise(path, model):
    """calibration.nc's dataset and table of a fit whose simulations are `model(values)` (one value per row), the
    residuals divided as the evaluator divides them."""
    from biostudy.calibration.methods import chosen
    from biostudy.calibration.noise import divisors, likelihood
    from biostudy.calibration.problem import load_calibration
    from biostudy.calibration.report import dataset, table_text

    plan = load_calibration(path)
    data = np.array([m.value for m in plan.measurements])
    divisor = divisors(plan.measurements, plan.noise)

    def evaluate(points):
        return [(model(plan.values(p)) - data) / divisor for p in points]

    result = chosen(plan.spec.method)(Objective(evaluate, len(data), np.full(len(data), 1e-9),
                                                 tuple(p.name for p in plan.parameters),
                                                 likelihood=likelihood(plan.noise)))
    ds = dataset(plan, result, model(plan.values(result.estimate.best.x)), COST, {}, {})
    return ds, table_text(ds)


def test_calibration_nc_and_its_table_give_the_estimated_sigma_and_no_p_value(tmp_path):
    times = np.array([0.02, 0.05, 0.08])

    def model(values):  # biomass and max_thickness grow linearly in r
        return np.concatenate([values["r"] / 100 * (1 + 10 * times), values["r"] / 50 * (1 + 10 * times[1:])])

    ds, text = fitted_with_noise(calibration(tmp_path, GROUPED, ESTIMATE), model)
    rows = slice(0, 3)
    residuals = ds.fitted.values[rows] - ds.measured.values[rows]
    sigma = math.sqrt(float(np.mean(residuals**2)))
    assert list(ds.noise_parameter.values) == ["sigma_b"] and str(ds.noise_units.values[0]) == "um"
    assert float(ds.noise_estimate[0]) == pytest.approx(sigma, rel=1e-9)  # σ̂² = SS/n of its rows at the estimate
    assert ds.noise_estimate.attrs["units"] == "um" and int(ds.noise_rows[0]) == 3
    assert float(ds.noise_lower[0]) < sigma < float(ds.noise_upper[0])
    np.testing.assert_allclose(ds.sigma.values, [sigma] * 3 + [0.1, 0.1], rtol=1e-9)
    np.testing.assert_allclose(ds.residual.values[rows], residuals / sigma, rtol=1e-9)
    assert list(ds.noise_name.values) == ["sigma_b"] * 3 + ["", ""]
    assert ds.attrs["objective"] == "-2 log L" and ds.attrs["dof"] == 5 - 1 - 1
    assert math.isnan(ds.attrs["chi2_p_value"])
    assert "| sigma_b | " in text and "-2 log L = " in text and "(p = " not in text
    assert "chi² and its p-value are not given" in text
    held, of_sigma = coverage(3, 1)
    assert ("The noise parameter sigma_b is estimated from 3 measurements for 1 parameter: with so few the 95 % "
            f"intervals are short (with a model linear in its parameters they would hold the truth {held * 100:.0f} % "
            f"of the time, σ's {of_sigma * 100:.0f} %: docs/calibration.md).**") in text  # one paragraph


def test_a_named_sigma_the_model_fits_exactly_is_said_in_words_not_a_crash(tmp_path):
    """Issue 39.2: two t = 0 replicates equal to the initial biomass share a named σ the model fits exactly at every
    parameter value: σ̂ = 0, -2 log L unbounded in it.  The fit of the other rows goes on; the σ is reported 0,
    without an interval, and calibration.md says why (it raised a math domain error after every simulation)."""
    rows = GROUPED.replace("\n", "\nbiomass\t\t0.0\t1.0\tsigma_zero\n" * 2, 1)  # before GROUPED's rows

    def model(values):  # the initial biomass, then GROUPED's rows as in the test above
        times = np.array([0.02, 0.05, 0.08])
        return np.concatenate([[1.0, 1.0], values["r"] / 100 * (1 + 10 * times),
                               values["r"] / 50 * (1 + 10 * times[1:])])

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning of a 0 / 0 residual reaches the user
        ds, text = fitted_with_noise(calibration(tmp_path, rows, ESTIMATE), model)
    assert list(ds.noise_parameter.values) == ["sigma_zero", "sigma_b"]
    assert float(ds.noise_estimate[0]) == 0.0 and np.isnan(ds.noise_lower[0]) and np.isnan(ds.noise_upper[0])
    assert 0 < float(ds.noise_lower[1]) < float(ds.noise_estimate[1]) < float(ds.noise_upper[1]) < math.inf
    assert np.isnan(ds.residual.values[:2]).all() and np.isfinite(ds.residual.values[2:]).all()
    assert ("**The model fits the 2 measurements of sigma_zero exactly (σ̂ = 0): their σ cannot be estimated (the "
            "likelihood grows without bound as σ shrinks) and has no interval, and they do not move with the "
            "parameters, so the estimate and intervals are those of the other rows (give their σ as a number in "
            "noiseParameters: the error you expect of them).**") in text
    assert "sigma_zero is estimated from" not in text  # no word of short intervals for a σ without one
    without, _ = fitted_with_noise(calibration(tmp_path, GROUPED, ESTIMATE), lambda values: model(values)[2:])
    assert float(ds.estimate[0]) == pytest.approx(float(without.estimate[0]), rel=1e-12)  # the others' fit, alone


def test_an_exact_fit_that_moves_with_the_parameters_is_said_to_draw_the_fit():
    from biostudy.calibration.noise import NoiseParameter
    from biostudy.calibration.report_noise import _exact
    from biostudy.fitting.likelihood import Sigma

    plan = SimpleNamespace(noise=[NoiseParameter("s", (0, 1), "um", 1.0)])
    for column, said in ((0.0, "they do not move with the parameters"), (0.5, "the fit is drawn to where the model "
                                                                               "goes through them")):
        found = SimpleNamespace(sigmas=[Sigma(0.0, math.nan, math.nan, 2)],
                                best=SimpleNamespace(jacobian=np.array([[column], [0.0], [1.0]])))
        (words,) = _exact(plan, found)
        assert said in words and "; " not in words  # statements are joined by '; '


def test_calibrate_estimates_sigma_from_the_tiny_colony_end_to_end(tmp_path):
    rows = named(*[("biomass", "", t, value, "sigma_biomass")
                   for t, value in ((0.02, 1.72), (0.04, 1.57), (0.06, 1.18), (0.08, 0.61))])  # g = 1e9, ± 0.03
    path = calibration(tmp_path, rows, '[estimate]\ng = [3e8, 3e9, "log"]\n[method]\nstarts = 1\nprofiles = false\n')
    result = invoke("calibrate", path, "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.output
    with xr.open_dataset(tmp_path / "out" / "calibration.nc") as ds:
        residuals = ds.fitted.values - ds.measured.values
        assert float(ds.noise_estimate[0]) == pytest.approx(math.sqrt(float(np.mean(residuals**2))), rel=1e-9)
        assert float(ds.noise_lower[0]) < float(ds.noise_estimate[0]) < float(ds.noise_upper[0])
    assert "| sigma_biomass | " in (tmp_path / "out" / "calibration.md").read_text()
    simulated = pd.read_csv(tmp_path / "out" / "simulation.tsv", sep="\t")  # PEtab's: the name, as the table had it
    assert list(simulated.noiseParameters) == ["sigma_biomass"] * 4
