"""A calibration's objective for pyPESTO (issue 36.1, `fitting.pypesto_objective`): pyPESTO's own optimiser finds
the least-squares solution of a linear model in closed form, its gradient check agrees with the finite-difference
sensitivities, its sampler runs on it; σ to estimate is refused, a failed simulation is a penalty.  The model is
analytic (no simulation): y = a + b t, a on a linear range, b on a log range."""
from __future__ import annotations

import numpy as np
import pytest

from biostudy.fitting import pypesto_objective
from biostudy.fitting.likelihood import PENALTY, Likelihood
from biostudy.fitting.objective import Objective

pypesto = pytest.importorskip("pypesto")

T = np.linspace(0.0, 1.0, 8)
SIGMA = 0.1
Y = 2.0 + 3.0 * T + np.random.default_rng(0).normal(0.0, SIGMA, T.size)
BOUNDS = [(0.0, 10.0, False), (0.01, 100.0, True)]  # a in [0, 10]; b in [0.01, 100], log


def values(u: np.ndarray) -> tuple[float, float]:
    return 10.0 * u[0], 10.0 ** (-2.0 + 4.0 * u[1])


def objective(fail=lambda a, b: False, **extra) -> Objective:
    def run(points):
        return [None if fail(*values(u)) else (values(u)[0] + values(u)[1] * T - Y) / SIGMA for u in points]

    return Objective(run, T.size, np.full(T.size, 1e-9), ("a", "b"), **extra)


def test_pypestos_optimiser_finds_the_least_squares_solution():
    import pypesto.optimize as optimize

    problem = pypesto_objective.problem(objective(), BOUNDS)
    assert problem.x_scales == ["lin", "log10"] and list(problem.ub) == [10.0, 2.0]
    result = optimize.minimize(problem, optimizer=optimize.ScipyOptimizer(method="ls_trf"), n_starts=2,
                               progress_bar=False)
    best = result.optimize_result.list[0]
    exact = np.linalg.lstsq(np.column_stack([np.ones_like(T), T]), Y, rcond=None)[0]
    np.testing.assert_allclose([best.x[0], 10.0 ** best.x[1]], exact, rtol=1e-6)
    assert best.fval == pytest.approx(0.5 * np.sum((((exact[0] + exact[1] * T) - Y) / SIGMA) ** 2), rel=1e-9)


def test_the_sensitivities_agree_with_pypestos_gradient_check():
    """biostudy's forward differences (a step of 0.01 of the range): exact for a, linear in it; for b = 10^x a
    forward difference of h = 0.04 in x is off by about ln(10) h / 2 = 4.6 % (the next term of Taylor's series)."""
    from pypesto.C import MODE_RES

    from biostudy.fitting.least_squares import STEP

    problem = pypesto_objective.problem(objective(), BOUNDS)
    x = np.array([2.5, np.log10(2.0)])
    check = problem.objective.check_grad(x, eps=1e-6, mode=MODE_RES, verbosity=0)
    h = STEP * 4.0  # in log10 b
    assert float(check["rel_err"]["a"]) < 1e-8
    assert float(check["rel_err"]["b"]) <= 1.05 * (10.0 ** h - 1.0 - h * np.log(10.0)) / (h * np.log(10.0))


def test_pypestos_sampler_runs_on_it():
    import pypesto.sample as sample

    problem = pypesto_objective.problem(objective(), BOUNDS)
    result = sample.sample(problem, n_samples=600, sampler=sample.AdaptiveMetropolisSampler(),
                           x0=np.array([2.0, np.log10(3.0)]))
    trace = result.sample_result.trace_x[0]
    assert trace.shape == (601, 2) and (trace >= problem.lb).all() and (trace <= problem.ub).all()
    assert abs(trace[200:, 0].mean() - 2.0) < 0.3  # a: its standard error here is 0.07


def test_sigma_to_estimate_is_refused_and_a_failed_simulation_is_a_penalty():
    with pytest.raises(ValueError, match="names σ to estimate .* give them as numbers for pyPESTO"):
        pypesto_objective.problem(objective(likelihood=Likelihood((np.arange(3),), (1.0,))), BOUNDS)
    found = pypesto_objective.Residuals(objective(fail=lambda a, b: a > 5.0), BOUNDS)
    np.testing.assert_array_equal(found.res(np.array([6.0, 0.0])), np.full(T.size, PENALTY))
    assert not found.sres(np.array([6.0, 0.0])).any()


def test_pypesto_problem_runs_biostudys_simulations_and_finds_what_calibrate_finds(tmp_path):
    """A calibration file's pyPESTO problem (`calibration.pypesto.pypesto_problem`): its residuals are the
    simulations' (data made by the model at r = 100 give zero there, so chi²_min = 0); pyPESTO's least squares
    ends within biostudy's own convergence tolerance of it (chi² < `least_squares.TOLERANCE`), near r = 100 as
    the standard error there says; `biostudy calibrate` into the same directory (the same owner: its case files
    are the same simulations) does the same."""
    import pypesto.optimize as optimize
    import xarray as xr
    from test_calibration_hostile import calibration, invoke

    from biostudy.calibration.pypesto import pypesto_problem
    from biostudy.fitting.least_squares import TOLERANCE

    rows = "observableId\ttime\tmeasurement\tnoiseParameters\nbiomass\t0.05\t{}\t0.2\nbiomass\t0.1\t{}\t0.2\n"
    path = calibration(tmp_path, rows.format(1.0, 1.0), "[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\n"
                                                        "profiles = false\n")
    with pypesto_problem(path, tmp_path / "out") as problem:
        model = 1.0 + 0.2 * problem.objective(np.array([100.0]), mode="mode_res")  # data + σ r at r = 100
    (tmp_path / "t.tsv").write_text(rows.format(*model))
    with pypesto_problem(path, tmp_path / "out") as problem:
        assert problem.objective(np.array([100.0]), mode="mode_res") == pytest.approx([0.0, 0.0], abs=1e-12)
        problem.set_x_guesses([[70.0]])
        result = optimize.minimize(problem, optimizer=optimize.ScipyOptimizer(method="ls_trf"), n_starts=1,
                                   progress_bar=False)
        best = result.optimize_result.list[0]
        jacobian = problem.objective(best.x, sensi_orders=(1,), mode="mode_res")
    assert 2 * best.fval < TOLERANCE  # chi² = 2 fval
    standard_error = 1.0 / np.sqrt(float(np.sum(jacobian**2)))
    assert abs(best.x[0] - 100.0) < np.sqrt(TOLERANCE) * standard_error * 1.01  # chi² = ((r - 100) / SE)² there
    done = invoke("calibrate", path, "-o", tmp_path / "out", "-q")
    assert done.exit_code == 0, done.output
    with xr.open_dataset(tmp_path / "out" / "calibration.nc") as ds:
        assert float(ds.attrs["chi2"]) < TOLERANCE
