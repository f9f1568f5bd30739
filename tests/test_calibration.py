"""`biostudy calibrate` (issue 18): a twin experiment at tiny size, a parameter the data cannot see, bad input,
and a calibration killed at a random moment and run again.

The twin: the 2-D agar colony on 12 x 16 cells of 1 µm (front velocity, 40 steps to T* = 0.2: the front moves
at most r/2 = 125 µm/T* at the upper bound of r, a Courant number of 0.6; its top stays below 9 µm, clear of
the lid), measured by the model itself at g = 1e9, r = 100 (`calibration.twin`): biomass and max_thickness at 1-4 h
with t_ref = 20 h, 5 % noise.  From two starts of a Latin hypercube (one in the lower, one in the upper part of
each range) least squares with profiles must find intervals that hold the truth.  The simulations (~0.1 s
each) make up most of this file's time; the kill-and-rerun test fits r alone from one start without profiles,
twice.
"""
from __future__ import annotations

import math
import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

from biostudy.calibration import twin
from biostudy.cli import app

SCENE = """\
name = "agar-twin"
description = "tiny 2-D colony on agar for calibration tests"
[grid]
shape = [12, 16]
[time]
t_end = 0.2
steps = 40
[[nutrient]]
shape = "face"
face = "y-"
[[biofilm]]
shape = "box"
lower = [3.0, 0.0]
upper = [9.0, 4.0]
[numerics]
advection = "tvd"
growth_velocity = "front"
"""
TRUTH = {"g": 1e9, "r": 100.0}
HOURS = [1.0, 2.0, 3.0, 4.0]  # T* = h / 20

CALIBRATION = """\
scene = "agar.toml"
[data]
measurements = "twin.tsv"
time_unit = "h"
t_ref = "20 h"
[estimate]
g = [1e7, 1e10, "log"]
r = [20.0, 250.0, "log"]
[method]
starts = 2
profiles = true
seed = 0
"""

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """The scene, the twin's table (made by the model at TRUTH) and the calibration file."""
    here = tmp_path_factory.mktemp("calibration")
    (here / "agar.toml").write_text(SCENE)
    (here / "twin.tsv").write_text(twin.table(here / "agar.toml", truth=TRUTH, observables_measured=[
        "biomass", "max_thickness"], times=HOURS, time_factor=1 / 20, noise=0.05, seed=1001))
    (here / "cal.toml").write_text(CALIBRATION)
    return here


@pytest.fixture(scope="module")
def fit_only(folder):
    """r alone in [50, 150] (g at its true value) from one start without profiles (the kill-and-rerun test runs it
    twice: what is killed and resumed is the same whatever the number of parameters), on 2 local workers (one
    pool for all rounds): the killed run, serial, must find the same to the last digit.  The only calibration
    of this file on workers, and the smallest: a pool inside the suite's own two processes oversubscribes."""
    text = CALIBRATION.replace("starts = 2", "starts = 1").replace("profiles = true", "profiles = false")
    text = text.replace('g = [1e7, 1e10, "log"]\n', "").replace("[20.0, 250.0", "[50.0, 150.0")
    (folder / "fit.toml").write_text(text.replace("[data]", '[set]\n"params.g" = 1e9\n[data]'))
    result = invoke("calibrate", folder / "fit.toml", "-o", folder / "fit-once", "-q", "--workers", "2")
    assert result.exit_code == 0, result.output
    return xr.load_dataset(folder / "fit-once" / "calibration.nc")


@pytest.fixture(scope="module")
def uninterrupted(folder):
    result = invoke("calibrate", folder / "cal.toml", "-o", folder / "once", "-q")  # serial: see `fit_only`
    assert result.exit_code == 0, result.output
    return result, xr.load_dataset(folder / "once" / "calibration.nc")


@pytest.mark.slow
def test_a_twin_is_recovered_within_its_95_percent_intervals_from_starts_near_the_bounds(folder, uninterrupted):
    result, ds = uninterrupted
    for name, truth in TRUTH.items():
        j = list(ds.parameter.values).index(name)
        assert ds.lower.values[j] <= truth <= ds.upper.values[j], (name, ds.lower.values[j], ds.upper.values[j])
        assert ds.lower.values[j] <= ds.estimate.values[j] <= ds.upper.values[j]  # at a bound, perhaps
        assert ds.standard_error.values[j] > 0
        # an interval reaching a bound is said in words (8 measurements of 5 % noise pin g and r only so far)
        closed = ds.low.values[j] < ds.lower.values[j] and ds.upper.values[j] < ds.high.values[j]
        assert bool(ds.identifiable.values[j]) == closed
        assert closed or f"the data do not determine {name}" in ds.attrs["statements"]
    unit = np.array([[(math.log10(v) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
                      for v, lo, hi in zip(row, ds.low.values, ds.high.values)] for row in ds.start_point.values])
    assert unit.min(axis=0).max() < 0.5 < unit.max(axis=0).min()  # each range started from its lower and upper part
    # chi² of a good fit to 8 measurements of 5 % noise with 2 parameters: within chi²(6)'s 99.9 % range
    assert ds.attrs["dof"] == 6 and 0.05 < ds.attrs["chi2"] < 22.5
    np.testing.assert_allclose(ds.time.values, np.array(HOURS * 2) / 20)
    assert np.all(ds.band_lower.values <= ds.fitted.values) and np.all(ds.fitted.values <= ds.band_upper.values)
    residual = (ds.fitted - ds.measured) / ds.sigma
    np.testing.assert_allclose(ds.residual.values, residual.values)
    assert float(np.sum(residual.values**2)) == pytest.approx(ds.attrs["chi2"], rel=1e-9)
    # the profiles lie above the lowest chi², and rise past the threshold where their intervals close
    assert np.nanmin(ds.profile_chi2.values) >= ds.attrs["chi2_minimum"] - 1e-9
    assert np.nanmax(ds.profile_chi2.values - ds.attrs["chi2_minimum"], axis=1).max() > 3.84
    assert "| g | " in result.stdout and "95 % profile interval" in result.stdout
    for name in ("calibration.md", "calibration_fit.png", "calibration_profiles.png"):
        assert (folder / "once" / name).is_file()
    assert ds.attrs["simulations"] == len(list((folder / "once" / "cases").glob("*.nc")))


POSTERIOR = '[method]\nname = "posterior"\nstarts = 2\ndesign = 16\nheld_out = 4\nsteps = 1500\nseed = 0\n'


@pytest.fixture(scope="module")
def sampled(folder, uninterrupted):
    """The twin's posterior (g and r), its directory seeded with the least-squares calibration's case files: the
    posterior's fit takes the same path from the same starts, so only its design and held-out runs are new."""
    (folder / "post.toml").write_text(CALIBRATION[:CALIBRATION.index("[method]")] + POSTERIOR)
    shutil.copytree(folder / "once" / "cases", folder / "post" / "cases")
    result = invoke("calibrate", folder / "post.toml", "-o", folder / "post", "-q", "--force")
    assert result.exit_code == 0, result.output
    return result, xr.load_dataset(folder / "post" / "calibration.nc")


@pytest.mark.slow
def test_the_posterior_s_long_lower_tail_agrees_with_the_profile(sampled, uninterrupted):
    """g's 2.5 % end, the far end of a long tail, held to the rule of the other ends: within a quarter of the
    profile interval's width (in log10).  With this seed (0) it is (log10 g = 7.30 against the profile's 7.87);
    with seed 1 it is not (8.76): the surrogate route's first-pass decisions move the far end of a long tail
    (docs/calibrate.md), so a change of the route that moves it shows here."""
    _, ds = sampled
    _, profiled = uninterrupted
    ends = np.log10([profiled.lower.values[0], profiled.upper.values[0]])
    assert abs(np.log10(ds.posterior_lower.values[0]) - ends[0]) < 0.25 * (ends[1] - ends[0])


@pytest.mark.slow
def test_the_posterior_of_a_twin_holds_the_truth_in_its_95_percent_credible_intervals(folder, sampled, uninterrupted):
    result, ds = sampled
    assert ds.sizes["sample"] >= 500
    for name, truth in TRUTH.items():
        j = list(ds.parameter.values).index(name)
        samples = ds[f"posterior_{name}"]
        assert samples.attrs["units"] == ds.units.values[j] and name in samples.attrs["long_name"]
        assert float(samples.min()) >= ds.low.values[j] and float(samples.max()) <= ds.high.values[j]
        assert ds.posterior_lower.values[j] <= truth <= ds.posterior_upper.values[j], (name, ds.posterior_lower.values[
            j], ds.posterior_upper.values[j])
        np.testing.assert_allclose(ds.posterior_median.values[j], np.median(samples.values))
        assert ds.surrogate_low.values[j] <= ds.posterior_lower.values[j]
        assert np.isfinite(ds.autocorrelation_time.values[j]) and ds.effective_samples.values[j] > 100
    # with a prior flat in log g, log r the 95 % credible intervals are the profile intervals of the same data where
    # the likelihood is near Gaussian (here curved, and sigma widened by the surrogate's error): each end within a
    # quarter of the profile interval's width, in log10 -- but g's lower end, the far end of a long tail, which
    # `test_the_posterior_s_long_lower_tail_agrees_with_the_profile` holds to the same, with what it rests on
    _, profiled = uninterrupted
    for j, ends_checked in ((0, [1]), (1, [0, 1])):
        ends = np.log10([profiled.lower.values[j], profiled.upper.values[j]])
        credible = np.log10([ds.posterior_lower.values[j], ds.posterior_upper.values[j]])
        off = np.abs(credible - ends)[ends_checked]
        assert np.all(off < 0.25 * (ends[1] - ends[0])), (ds.parameter.values[j], credible, ends)
    # the design and the held-out runs are the only new simulations: the fit's were in the copied case files
    # (16, 8 more each time the box was widened, 8 drawn from the first posterior)
    designed = ds.attrs["surrogate_design_runs"]
    assert designed in (24, 32, 40, 48) and (designed - 24) // 8 == ds.attrs["surrogate_box_widened"]
    assert ds.attrs["simulations"] == designed + 4 and ds.attrs["simulations_reused"] >= 20
    assert ds.attrs["surrogate_held_out_runs"] == 4 and ds.attrs["surrogate_training_from_fit"] >= 5
    assert ds.attrs["surrogate_training_runs"] == designed + ds.attrs["surrogate_training_from_fit"]
    assert 0.15 < ds.attrs["acceptance_fraction"] < 0.9
    # the likelihood's sigma: the measurement's with the surrogate's held-out error added in quadrature
    np.testing.assert_allclose(ds.sigma_likelihood.values, ds.sigma.values * np.sqrt(1 + ds.surrogate_error.values**2))
    assert np.all(ds.posterior_band_lower.values < ds.posterior_band_upper.values)
    assert "posterior median" in result.stdout and "95 % credible interval" in result.stdout
    assert (folder / "post" / "calibration_corner.png").is_file()
    assert not (folder / "post" / "calibration_profiles.png").exists()  # no profiles unless asked


@pytest.mark.slow
def test_a_posterior_calibration_run_again_repeats_no_simulation_and_finds_the_same(folder, sampled):
    _, first = sampled
    before = _finished(folder / "post")
    again = invoke("calibrate", folder / "post.toml", "-o", folder / "post", "-q")
    assert again.exit_code == 0 and "0 simulations run" in again.stderr, again.stderr
    assert _finished(folder / "post") == before
    ds = xr.load_dataset(folder / "post" / "calibration.nc")
    for name in ("posterior_g", "posterior_r", "surrogate_error", "posterior_band_upper"):
        np.testing.assert_array_equal(ds[name].values, first[name].values, err_msg=name)


def _finished(directory: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (directory / "cases").glob("*.nc")}


@pytest.mark.slow
def test_a_calibration_killed_at_a_random_moment_resumes_without_repeating_a_simulation(folder, fit_only):
    expected = fit_only
    out = folder / "killed"
    seed = random.randrange(1 << 16)
    wanted = random.Random(seed).randint(1, 4)  # the moment: after this many finished simulations
    process = subprocess.Popen([sys.executable, "-m", "biostudy", "calibrate", str(folder / "fit.toml"), "-o",
                                str(out), "-q"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while len(list((out / "cases").glob("*.nc"))) < wanted and time.monotonic() < deadline:
            if process.poll() is not None:
                break
            time.sleep(0.02)
        process.send_signal(signal.SIGKILL)
    finally:
        process.kill()
        process.wait()
    before = _finished(out)
    assert before and not (out / "calibration.nc").exists(), f"killed too late (seed {seed})"
    result = invoke("calibrate", folder / "fit.toml", "-o", out, "-q")
    assert result.exit_code == 0, result.output
    after = _finished(out)
    assert all(after[name] == stamp for name, stamp in before.items()), f"a finished simulation ran again ({seed})"
    ds = xr.load_dataset(out / "calibration.nc")
    assert ds.attrs["simulations"] + ds.attrs["simulations_reused"] >= len(after)
    assert ds.attrs["simulations_reused"] >= len(before) - 1  # the one being written at the kill may be lost
    assert expected.sizes["parameter"] == 1 and expected.attrs["simulations"] >= 5
    for name in ("estimate", "standard_error", "correlation", "fitted", "band_upper"):
        np.testing.assert_array_equal(ds[name].values, expected[name].values, err_msg=f"{name} (seed {seed})")
    assert ds.attrs["chi2"] == expected.attrs["chi2"]
    again = invoke("calibrate", folder / "fit.toml", "-o", out, "-q")
    assert again.exit_code == 0 and "0 simulations run" in again.stderr, again.stderr
    np.testing.assert_array_equal(xr.load_dataset(out / "calibration.nc").estimate.values, expected.estimate.values)


def test_k_alpha_from_biomass_alone_is_not_identifiable(folder):
    # k_alpha's phi source k_alpha alpha ~ k_alpha² t stays far below 5 % of the biomass over 4 h: the data cannot
    # see it, so its profile stays below the threshold up to a bound
    (folder / "biomass.tsv").write_text(twin.table(folder / "agar.toml", truth={"k_alpha": 1e-3},
                                                   observables_measured=["biomass"], times=HOURS, time_factor=1 / 20,
                                                   noise=0.05, seed=4))
    (folder / "k_alpha.toml").write_text(CALIBRATION.replace("twin.tsv", "biomass.tsv").replace(
        'g = [1e7, 1e10, "log"]\nr = [20.0, 250.0, "log"]', 'k_alpha = [1e-4, 1e-1, "log"]').replace("starts = 2",
                                                                                                 "starts = 1"))
    result = invoke("calibrate", folder / "k_alpha.toml", "-o", folder / "k_alpha", "-q")
    assert result.exit_code == 0, result.output
    ds = xr.load_dataset(folder / "k_alpha" / "calibration.nc")
    assert not bool(ds.identifiable.values[0])
    assert ds.lower.values[0] == pytest.approx(1e-4) or ds.upper.values[0] == pytest.approx(1e-1)
    assert "the data do not determine k_alpha" in result.stdout.replace("**T", "t")
    assert "the data do not determine k_alpha" in ds.attrs["statements"]


# ---- bad input: each one line, exit 2, naming the file, the line or the key ---------------------------------------

TABLE = """\
observableId\ttime\tmeasurement\tnoiseParameters
biomass\t1\t2.9\t0.15
biomass\t2\t3.7\t0.18
"""


@pytest.mark.parametrize("table, calibration, expected", [
    (TABLE.replace("biomass\t2", "biomas\t2"), None,
     "t.tsv: line 3: observableId: unknown observable 'biomas' (did you mean 'biomass'?)"),
    (TABLE.replace("\t2\t3.7", "\t30\t3.7"), None,
     "t.tsv: line 3: time: 30 h is T* = 1.5 (t_ref = 20 h), after the run's end: the scene runs over T* = 0 to 0.2"),
    (TABLE.replace("0.18", "0"), None, "t.tsv: line 3: noiseParameters: the standard deviation must be > 0 (got 0)"),
    (TABLE.replace("0.18", "-1"), None, "t.tsv: line 3: noiseParameters: the standard deviation must be > 0"),
    (TABLE.replace("\t0.18", "\t"), None, "t.tsv: line 3: noiseParameters: missing (the standard deviation sigma"),
    (TABLE.replace("\tnoiseParameters", ""), None, "t.tsv: missing column noiseParameters"),
    (TABLE.replace("3.7", "abc"), None, "t.tsv: line 3: measurement: not a number (got 'abc')"),
    (TABLE, 'gg = [1.0, 2.0]', "c.toml: estimate.gg: the scene has no key gg (did you mean 'g'?)"),
    (TABLE, 'g = [-1.0, 1e9]', "c.toml: estimate.g: low end -1 leaves the allowed values (params.g): must be >= 0"),
    (TABLE, 'r = [400.0, 20.0]', "c.toml: estimate.r: low end 400 must be below the high end 20"),
    (TABLE, 'nu = [0.2, 0.6]', "c.toml: estimate.nu: high end 0.6 leaves the allowed values (params.nu): must be <"),
    (TABLE, '"time.steps" = [10.0, 20.0]', "c.toml: estimate.time.steps: time.steps is not a real number"),
    (TABLE.replace("noiseParameters\n", "noiseParameters\tsimulationConditionId\n").replace("0.15\n", "0.15\ta\n")
     .replace("0.18\n", "0.18\ta\n"), 'r = [20.0, 400.0]\n[conditions.a]\n"params.gg" = 1.0',
     "c.toml: case condition a: params.gg: unknown key (did you mean 'g'?)"),
    (TABLE.replace("noiseParameters\n", "noiseParameters\tsimulationConditionId\n").replace("0.15\n", "0.15\tb\n")
     .replace("0.18\n", "0.18\ta\n"), 'r = [20.0, 400.0]\n[conditions.a]\n"params.k" = 2.0',
     "t.tsv: line 2: simulationConditionId: unknown condition 'b' (conditions are a)"),
    (TABLE, 'r = [20.0, 400.0]\n[method]\ndesign = 10', 'c.toml: method.design: applies to name = "posterior" only'),
    (TABLE, 'r = [20.0, 400.0]\n[method]\nname = "posterior"\nheld_out = 0', "c.toml: method.held_out: must be >= 1"),
    (TABLE, 'r = [20.0, 400.0]\n[method]\nname = "posterior"\nsamples = 10',
     "c.toml: method.samples: unknown key"),
    (TABLE, 'r = [20.0, 400.0]\ng = [1.0, 2.0]\nk = [1.0, 3.0]\n[method]\nname = "posterior"\nwalkers = 5',
     "c.toml: method.walkers: emcee needs at least twice as many walkers as parameters: 5 < 2 x 3"),
], ids=["unknown observable", "time outside the run", "sigma 0", "sigma negative", "sigma missing",
        "missing column", "not a number", "key the scene lacks", "bound outside", "low >= high", "high end outside",
        "integer key", "condition with an unknown key", "unknown condition",
        "posterior key for least squares", "no held-out run", "unknown posterior key", "too few walkers"])
def test_bad_input_is_one_line(write_toml, tmp_path, table, calibration, expected):
    write_toml("agar.toml", SCENE)
    write_toml("t.tsv", table)
    estimate = calibration or 'r = [20.0, 400.0, "log"]'
    path = write_toml("c.toml", textwrap.dedent("""\
        scene = "agar.toml"
        [data]
        measurements = "t.tsv"
        time_unit = "h"
        t_ref = "20 h"
        [estimate]
        """) + estimate + "\n")
    result = invoke("calibrate", path, "-o", tmp_path / "out", "-q")
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output, result.stderr
    assert expected in lines[0], lines[0]
    assert not (tmp_path / "out").exists()  # refused before anything ran or was written


def test_every_problem_of_a_table_at_once_and_a_unit_that_is_not_a_time(write_toml, tmp_path):
    write_toml("agar.toml", SCENE)
    write_toml("t.tsv", TABLE.replace("2.9", "x").replace("0.18", "0"))
    path = write_toml("c.toml", 'scene = "agar.toml"\n[data]\nmeasurements = "t.tsv"\ntime_unit = "h"\n'
                                't_ref = "20 h"\n[estimate]\nr = [20.0, 400.0]\n')
    result = invoke("calibrate", path, "-q", "-o", path.parent / "out")
    assert result.exit_code == 2
    assert result.stderr.count("error: ") == 2 and "line 2: measurement" in result.stderr and "line 3: noise" in \
        result.stderr
    path.write_text(path.read_text().replace('t_ref = "20 h"', 't_ref = "20 m"'))
    result = invoke("calibrate", path, "-q", "-o", path.parent / "out")
    assert result.exit_code == 2 and "c.toml: data.t_ref: '20 m' is not a time" in result.stderr, result.stderr


def test_a_calibration_file_shows_what_one_simulation_needs(folder):
    result = invoke("show", folder / "cal.toml")
    assert result.exit_code == 0, result.output
    assert "2 parameters, 8 measurements, 1 conditions of agar.toml" in result.stdout


def test_the_bundled_example_validates():
    from biostudy.calibration.problem import load_calibration
    from biostudy.inputs import bundled

    plan = load_calibration(bundled.resolve("calibrate-agar"))
    assert [p.name for p in plan.parameters] == ["g", "r"] and len(plan.measurements) >= 10
    assert os.path.samefile(plan.data_file, bundled.studies_dir() / "calibrate-agar.tsv")


def test_conditions_share_parameters_unless_they_estimate_their_own(write_toml):
    from biostudy.calibration.problem import load_calibration

    write_toml("agar.toml", SCENE)
    write_toml("t.tsv", "observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters\n"
                        "biomass\tfull\t1\t2.9\t0.15\nbiomass\thalf\t2\t2.5\t0.15\nbiomass\thalf\t4\t3.1\t0.15\n")
    path = write_toml("c.toml", textwrap.dedent("""\
        scene = "agar.toml"
        [data]
        measurements = "t.tsv"
        time_unit = "min"
        t_ref = "20 h"
        [estimate]
        g = [1e7, 1e10, "log"]
        r = [20.0, 250.0, "log"]
        [conditions.full]
        [conditions.half]
        "nutrient.0.value" = 0.5
        [conditions.half.estimate]
        r = [20.0, 250.0]
        """))
    plan = load_calibration(path)
    assert [(p.name, p.conditions) for p in plan.parameters] == [("g", ("full", "half")), ("r", ("full",)),
                                                                  ("r[half]", ("half",))]
    np.testing.assert_allclose(plan.times, np.array([1.0, 2.0, 4.0]) / 1200)  # minutes over 20 h
    values = plan.values(np.array([0.5, 0.0, 1.0]))
    assert values == {"g": pytest.approx(10**8.5), "r": 20.0, "r[half]": 250.0}
    half = plan.scene_at("half", values)
    assert half.params.r == 250.0 and half.params.g == pytest.approx(10**8.5) and half.nutrient[0].value == 0.5
    assert list(half.time.times()) == pytest.approx([2 / 1200, 4 / 1200, 0.2])  # its own times, then t_end
    full = plan.scene_at("full", values)
    assert full.params.r == 20.0 and full.nutrient[0].value == 1.0
    write_toml("c.toml", path.read_text() + '[conditions.third]\n"params.k" = 2.0\n')
    result = invoke("calibrate", path, "-q", "-o", path.parent / "out")
    assert result.exit_code == 2 and "c.toml: conditions.third: no row of the measurement table names it" in \
        result.stderr, result.stderr


@pytest.mark.slow  # with the fixture the kill-and-rerun test makes anyway
def test_calibrated_rates_carry_their_units_per_t_star_and_per_hour(folder, fit_only):
    """Issue 26.1: r is µm/T* (pint reads µm: T* is dimensionless), and µm/h with t_ref = 20 h."""
    import cf_xarray.units
    import pint_xarray  # noqa: F401  (the .pint accessor)

    ds = fit_only
    registry = cf_xarray.units.units
    quantified = ds.pint.quantify(unit_registry=registry)
    r = float(ds.estimate.sel(parameter="r"))
    assert quantified["estimate_r"].pint.units == registry.micrometer  # µm/T*, T* dimensionless
    assert "um/T*" in ds["estimate_r"].attrs["long_name"] and str(ds.units_model.sel(parameter="r").values) == "um/T*"
    per_hour = quantified["estimate_r_real"]
    assert per_hour.pint.units == registry.micrometer / registry.hour
    assert float(per_hour.pint.magnitude) == pytest.approx(r / 20)
    assert "lower_r_real" in ds  # NaN: no profiles
    assert "units" not in ds.estimate.attrs  # mixed units: none, rather than a wrong "1"
    table = (folder / "fit-once" / "calibration.md").read_text()
    assert f"| r | {r:.4g} µm/T*" in table.replace("e+0", "e").replace("e-0", "e-")
    assert "Rates in real time (t_ref = 20 h)" in table and f"| r | {r / 20:.4g} µm/h | - |" in table
    from biostudy.calibration.pictures import profiles_figure

    figure = profiles_figure(ds)
    assert figure.axes[0].get_xlabel() == "r (µm/T*)"  # was "r (µm)"
    figure.clear()
