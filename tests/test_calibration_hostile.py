"""Calibration files as a hostile user writes them (issue 25): condition names that are paths, costs that cannot
fit, extreme table numbers, the same key under two spellings, too few measurements.  Most are checks made before
anything runs; the few that simulate use a 8 x 8 colony of 10 steps (a few hundredths of a second each).
"""
from __future__ import annotations

import hashlib
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from biostudy.cli import app

SCENE = """\
name = "speck"
[grid]
shape = [8, 8]
[time]
t_end = 0.1
steps = 10
[[nutrient]]
shape = "face"
face = "y-"
[[biofilm]]
shape = "box"
lower = [2.0, 0.0]
upper = [6.0, 3.0]
"""

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def table(*rows: tuple[str, str, float, float, float]) -> str:
    """A measurement table: (observable, condition, time in h, measurement, sigma) per row."""
    lines = ["observableId\tsimulationConditionId\ttime\tmeasurement\tnoiseParameters"]
    return "\n".join(lines + ["\t".join(map(str, row)) for row in rows]) + "\n"


def calibration(folder: Path, rows: str, body: str, scene: str = SCENE) -> Path:
    """The scene, the table and a calibration file (times in h, t_ref = 1 h) in `folder`; `body` follows [data]."""
    (folder / "speck.toml").write_text(scene)
    (folder / "t.tsv").write_text(rows)
    path = folder / "c.toml"
    path.write_text('scene = "speck.toml"\n[data]\nmeasurements = "t.tsv"\ntime_unit = "h"\nt_ref = "1 h"\n'
                    + textwrap.dedent(body))
    return path


def one_line(result, expected: str) -> str:
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in result.output, result.stderr
    assert expected in lines[0], lines[0]
    return lines[0]


# ---- 1. a condition's name is a name, never a path -----------------------------------------------------------------

def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_conditions_named_like_paths_write_their_case_files_under_cases(tmp_path):
    from biostudy.calibration.evaluator import Evaluator
    from biostudy.commands.calibrate import load
    from biostudy.execution.jobs import Execution

    folder = tmp_path / "lab"
    folder.mkdir()
    victim = folder / "victim.nc"
    victim.write_bytes(b"the user's own results")
    before = _digest(victim)
    elsewhere = tmp_path / "elsewhere" / "absolute"
    hostile = ["../../victim", str(elsewhere), "day1/rep2"]
    # "a" estimates r for itself; the hostile conditions estimate nothing, so their case ids are their names alone
    rows = table(*(("biomass", name, 0.05, 1.0, 0.1) for name in ["a", *hostile]))
    path = calibration(folder, rows, "[conditions.a.estimate]\nr = [50.0, 150.0]\n"
                       + "".join(f'[conditions."{name}"]\n"params.k" = 2.0\n' for name in hostile))
    out = folder / "out"
    simulations = Evaluator(load(path, directory=out).plan, out, Execution())
    [residuals] = simulations.evaluate([np.array([0.5])])
    assert residuals is not None and np.all(np.isfinite(residuals))
    assert _digest(victim) == before and not (tmp_path / "elsewhere").exists()
    written = sorted(p for p in tmp_path.rglob("*.nc") if p != victim)
    assert len(written) == 4 and all(p.parent == out / "cases" for p in written), written
    names = {p.stem for p in written}
    assert {"..-..-victim", "day1-rep2", "-".join(str(elsewhere).split("/"))} < names, names  # still readable


def test_conditions_whose_names_collide_as_file_names_are_refused(tmp_path):
    rows = table(("biomass", "day1/rep2", 0.05, 1.0, 0.1), ("biomass", "day1-rep2", 0.05, 1.0, 0.1))
    path = calibration(tmp_path, rows, """\
        [estimate]
        r = [50.0, 150.0]
        [conditions."day1/rep2"]
        [conditions.day1-rep2]
        """)
    one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"),
             "conditions day1/rep2 and day1-rep2 collide as file names")
    assert not (tmp_path / "out").exists()


# ---- 11, 14: checks of the estimated keys before anything runs -----------------------------------------------------

TWO_ROWS = table(("biomass", "", 0.05, 1.0, 0.1), ("biomass", "", 0.08, 1.2, 0.1))


@pytest.mark.parametrize("body, expected", [
    ('[estimate]\ng = [1e7, 1e10, "log"]\n"params.g" = [1e7, 1e10, "log"]\n',
     "c.toml: estimate.params.g: is the same key as g"),
    ('[estimate]\nr = [20.0, 250.0]\n[conditions.a]\n[conditions.a.estimate]\ng = [1e7, 1e10]\n'
     '"params.g" = [1e8, 1e9]\n', "c.toml: conditions.a.estimate.params.g: is the same key as g"),
    ('[estimate]\n"time.t_end" = [0.01, 0.2]\n',
     "c.toml: estimate.time.t_end: low end 0.01 ends a run before the measurement at T* = 0.08 (t.tsv, line 3)"),
    ('[estimate]\nr = [20.0, 250.0]\n[conditions.a]\n[conditions.a.estimate]\n"time.t_end" = [0.01, 0.2]\n',
     "c.toml: conditions.a.estimate.time.t_end: low end 0.01 ends a run before the measurement at T* = 0.08"),
], ids=["two spellings", "two spellings in a condition", "t_end before a measurement", "a condition's own t_end"])
def test_estimated_keys_are_checked_before_anything_runs(tmp_path, body, expected):
    rows = TWO_ROWS.replace("\t\t", "\ta\t") if "conditions.a" in body else TWO_ROWS
    path = calibration(tmp_path, rows, body)
    one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"), expected)
    assert not (tmp_path / "out").exists()
    one_line(invoke("show", path), expected)


def test_a_key_shared_and_estimated_by_a_condition_under_another_spelling_is_the_condition_s_own(tmp_path):
    from biostudy.calibration.problem import load_calibration

    path = calibration(tmp_path, TWO_ROWS.replace("\t\t0.05", "\ta\t0.05").replace("\t\t", "\tb\t"), """\
        [estimate]
        r = [20.0, 250.0]
        [conditions.a]
        [conditions.b.estimate]
        "params.r" = [20.0, 250.0]
        """)
    plan = load_calibration(path)
    assert [(p.name, p.conditions) for p in plan.parameters] == [("r", ("a",)), ("r[b]", ("b",))]


# ---- 6. what a calibration costs is said before it runs, and refused when it cannot fit -------------------------

def _many_times(n: int) -> str:
    """A table of n distinct times inside the speck's run (T* 0 to 0.1)."""
    return table(*(("biomass", "", 0.1 * (i + 1) / n, 1.0, 0.1) for i in range(n)))


def test_a_table_of_many_distinct_times_is_refused_when_its_outputs_cannot_fit_and_show_says_so(tmp_path,
                                                                                               monkeypatch):
    # 20,000 outputs of 8 x 8 cells: ~0.2 GB held three times over, beside the process's 0.32 GB
    path = calibration(tmp_path, _many_times(20_000), '[estimate]\nr = [20.0, 250.0]\n')
    monkeypatch.setenv("BIOSTUDY_MEMORY", "500 MB")
    refused = one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"),
                       "t.tsv: 20,000 outputs per simulation of condition scene (one per distinct measurement time): "
                       "needs ~")
    assert "500 MB available" in refused and not (tmp_path / "out").exists()
    shown = invoke("show", path)
    assert shown.exit_code == 0, shown.output
    memory = refused.split("needs ")[1].split(" of memory")[0]
    assert f"one simulation {memory} of memory" in shown.stdout and "20,000 outputs per simulation" in shown.stdout


def test_many_outputs_are_said_before_the_first_simulation_runs(tmp_path, monkeypatch):
    from biostudy.commands import calibrate
    from biostudy.errors import Failed

    def stopped(*args, **kwargs):
        raise Failed("stopped before the fit")

    monkeypatch.setattr(calibrate.Evaluator, "objective", stopped)
    path = calibration(tmp_path, _many_times(1_500), '[estimate]\nr = [20.0, 250.0]\n')
    result = invoke("calibrate", path, "-o", tmp_path / "out", "-q")
    assert result.exit_code == 1 and "stopped before the fit" in result.stderr, result.output
    assert "1,500 outputs per simulation of condition scene" in result.stderr.split("stopped")[0]


def test_posterior_chains_that_cannot_fit_are_refused_before_anything_runs(tmp_path):
    path = calibration(tmp_path, TWO_ROWS, '[estimate]\nr = [20.0, 250.0]\n[method]\nname = "posterior"\n'
                                           'walkers = 1000\nsteps = 1000000\n')
    one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"),
             "c.toml: method.steps: the posterior's chains (1000 walkers × 1000000 steps × 1 parameters) need ~32 GB "
             "of memory, 16 GB available (BIOSTUDY_MEMORY=16 GB): lower steps or walkers")
    assert not (tmp_path / "out").exists()
    shown = invoke("show", path)
    assert shown.exit_code == 0 and "chains        ~32 GB of memory" in shown.stdout, shown.output


# ---- 12. what the fit says about the parameters, in words -----------------------------------------------------------

COST = {"simulations": 0, "simulations_reused": 0, "rounds": 0, "wall_time": 0.0, "wall_time_simulations": 0.0,
        "wall_time_reading": 0.0}


def fitted(folder: Path, rows: str, body: str, model):
    """calibration.nc's dataset and table of a fit whose simulations are `model(values) -> one value per row`
    (an analytic model in place of the solver: what is tested is what the fit's numbers are said as)."""
    from biostudy.calibration.methods import chosen
    from biostudy.calibration.problem import load_calibration
    from biostudy.calibration.report import dataset, table_text
    from biostudy.fitting.objective import Objective

    plan = load_calibration(calibration(folder, rows, body))
    data = np.array([m.value for m in plan.measurements])
    sigma = np.array([m.sigma for m in plan.measurements])

    def evaluate(points):
        return [(model(plan.values(p)) - data) / sigma for p in points]

    result = chosen(plan.spec.method)(Objective(evaluate, len(data), np.full(len(data), 1e-9),
                                                 tuple(p.name for p in plan.parameters)))
    ds = dataset(plan, result, model(plan.values(result.estimate.best.x)), COST, {}, {})
    return ds, table_text(ds)


def test_a_parameter_the_data_cannot_see_is_not_identifiable_without_profiles(tmp_path):
    ds, text = fitted(tmp_path, TWO_ROWS, '[estimate]\ng = [1e7, 1e10, "log"]\nr = [20.0, 250.0]\n'
                                          '[method]\nstarts = 1\nprofiles = false\n',
                      lambda values: np.array([values["r"] / 100, values["r"] / 80]))
    j = list(ds.parameter.values).index("g")
    assert np.isinf(ds.standard_error.values[j]) and not bool(ds.identifiable.values[j])
    assert "| g | " in text and "| inf | - | no |" in text


def test_fewer_measurements_than_parameters_are_said_in_words(tmp_path):
    ds, text = fitted(tmp_path, table(("biomass", "", 0.05, 1.0, 0.1)),
                      '[estimate]\ng = [1e7, 1e10, "log"]\nr = [20.0, 250.0]\n[method]\nstarts = 1\nprofiles = false\n',
                      lambda values: np.array([values["r"] / 100 + np.log10(values["g"]) / 10]))
    assert "degrees of freedom" not in text and "-1" not in text
    assert "1 measurement for 2 parameters: the data cannot determine them all" in text
    assert "1 measurement for 2 parameters" in ds.attrs["statements"]
    assert not np.any(ds.identifiable.values)


# ---- 8, 10: numbers a fit cannot compute with, and sigma in the wrong unit --------------------------------------

@pytest.mark.parametrize("measurement, sigma, expected", [
    (1.0, 1e-320, "t.tsv: line 2: noiseParameters: σ = 1e-320 lies outside 1e-100 to 1e100"),
    (1e308, 0.1, "t.tsv: line 2: measurement: 1e+308 lies outside -1e100 to 1e100,"),
    (1.0, 1e308, "t.tsv: line 2: noiseParameters: σ = 1e+308 lies outside 1e-100 to 1e100"),
    (1e90, 1e-20, "t.tsv: line 2: noiseParameters: the measurement is 1e+110 σ from 0"),
], ids=["sigma 1e-320", "measurement 1e308", "sigma 1e308", "measurement over sigma 1e110"])
def test_table_numbers_beyond_what_a_fit_computes_with_are_one_line(tmp_path, measurement, sigma, expected):
    path = calibration(tmp_path, table(("biomass", "", 0.05, measurement, sigma), ("biomass", "", 0.08, 1.2, 0.1)),
                       '[estimate]\nr = [20.0, 250.0]\n')
    one_line(invoke("calibrate", path, "-o", tmp_path / "out", "-q"), expected)
    assert not (tmp_path / "out").exists()


def test_sigma_in_the_wrong_unit_says_how_far_the_fit_is_not_that_every_evaluation_failed(tmp_path):
    from biostudy.errors import Failed

    with pytest.raises(Failed) as error:  # sigma 1e-8 of measurements of order 1: every residual ~1e8 sigma
        fitted(tmp_path, TWO_ROWS.replace("\t0.1\n", "\t1e-08\n"), '[estimate]\nr = [20.0, 250.0]\n'
               '[method]\nstarts = 1\nprofiles = false\n', lambda values: np.array([values["r"] / 100, 0.5]))
    said = str(error.value)
    assert "every evaluation" not in said and "e+07 σ from the measurement of line 3" in said, said
    assert "is σ (noiseParameters) in the measurement's units?" in said


# ---- Ctrl-C during a fit (issue 28: no threads in the driver) -------------------------------------------------------

def test_ctrl_c_between_rounds_ends_the_calibration_at_once_and_its_finished_runs_are_reused(tmp_path, monkeypatch):
    from biostudy.calibration import evaluator

    path = calibration(tmp_path, TWO_ROWS, '[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 2\nprofiles = false\n')
    out = tmp_path / "out"
    real = evaluator.run_jobs

    def interrupted_at_the_second_round(calls: list):
        def run_jobs(jobs, *args, **kwargs):
            if len(calls) == 1:
                raise KeyboardInterrupt  # as Ctrl-C lands while the second round runs
            report = real(jobs, *args, **kwargs)
            calls.append((len(report.ran), len(report.skipped)))
            return report
        return run_jobs

    for skipped in (0, 2):  # the second time, the first round's runs are read back, not run again
        calls: list = []
        monkeypatch.setattr(evaluator, "run_jobs", interrupted_at_the_second_round(calls))
        result = invoke("calibrate", path, "-o", out, "-q")
        assert result.exit_code == 130 and "Traceback" not in result.output, result.output
        assert calls == [(2 - skipped, skipped)] and not (out / "calibration.nc").exists()
        assert len(list((out / "cases").glob("*.nc"))) == 2  # the first round's two starts, recorded
