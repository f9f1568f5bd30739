"""Does the grid or the biology misfit?  A calibration's simulations at the optimum, each measured observable's
discretisation error against the measurement's σ (`biostudy calibrate --error-estimate`, issue 34.4).

At the optimum every condition's simulation has run (the fit evaluated it); its companions
(`plans.companions`) run as jobs beside it (`execution.case_errors`: DIR/cases/<id>~<companion>.nc, reused on a
re-run), and each measured observable's estimated discretisation error (`quantities.error_bars`) is read at the
row's time.  A row whose error exceeds `RATIO` σ (a tenth of the variance: the fit's χ² grows by about 0.1 per
such row from the grid alone) is one the fit cannot tell from the data: calibration.md says so in words, naming
the rows, and calibration.nc keeps per row `discretisation_error` and `discretisation_to_sigma`.  The error is
not added to σ² in the likelihood (the issue's option, not done): the words ask for a finer grid instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data import case_files, reading
from ..execution.case_errors import SEPARATOR, companion_jobs
from ..execution.jobs import run_jobs
from ..formatting import number
from ..quantities import error_bars
from .evaluator import Evaluator

RATIO = 0.3


@dataclass
class GridError:
    """Per measurement row the estimated discretisation error of its simulated observable at the optimum (NaN
    where not estimated), and per condition how it was estimated (or why not)."""

    errors: np.ndarray
    said: list[str]


def _done(runs: Evaluator, job_id: str, scene):
    path = case_files.case_file(runs.directory, job_id)
    record = case_files.recorded(path)
    if not record or record.get("status") != "done":
        return None
    ds = reading.open_dataset(path)
    ds.attrs.update(scene.substratum_attrs())  # as the scene says now, as the evaluator reads it
    return ds


def at_optimum(runs: Evaluator, point: np.ndarray) -> GridError:
    """The companions of the optimum's simulations run (with the calibration's workers), the errors read."""
    plan = runs.plan
    jobs = [runs.job(condition, plan.values(point)) for condition in plan.conditions]
    extra, notes = companion_jobs(jobs)
    if extra:
        report = run_jobs(extra, runs.directory, runs.execution, backend=runs.backend)
        runs.ran += report.ran
        runs.reused += report.skipped
    errors = np.full(len(plan.measurements), np.nan)
    said = []
    for condition, job in zip(plan.conditions, jobs):
        run = _done(runs, job.id, job.scene)
        if run is None:
            said.append(f"{condition}: its simulation at the optimum did not finish")
            continue
        companions = {name: _done(runs, f"{job.id}{SEPARATOR}{name}", job.scene) for name in notes[job.id]}
        rows = runs.rows[condition]
        names = list(dict.fromkeys(plan.measurements[i].observable for i in rows))
        scheme = job.scene.numerics.advection
        variables, attrs = error_bars.estimate(run, companions, notes[job.id], scheme, names)
        said.append(f"{condition}: {str(attrs[error_bars.ATTRIBUTE]).removeprefix('not estimated: ')}")
        times = run["time"].values
        for i in rows:
            index = int(np.argmin(np.abs(times - plan.times[i])))
            errors[i] = variables[f"{plan.measurements[i].observable}{error_bars.SUFFIX}"].values[index]
    return GridError(errors, said)


def variables(grid: GridError, sigma: np.ndarray, units: list[str]) -> dict:
    """calibration.nc's per-row variables: the error and its ratio to σ."""
    ratio = _ratio(grid, sigma)
    unit = units[0] if len(set(units)) == 1 else "1"
    return {"discretisation_error": ("measurement", grid.errors,
                                     {"units": unit, "long_name": "estimated discretisation error of the simulated "
                                                                  "observable at the optimum (its row's units)"}),
            "discretisation_to_sigma": ("measurement", ratio,
                                        {"units": "1", "long_name": "discretisation error over the measurement's "
                                                                    "sigma"})}


def _ratio(grid: GridError, sigma: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(sigma > 0, grid.errors / sigma, np.nan)


def exceeding(grid: GridError, sigma: np.ndarray) -> list[int]:
    """The rows whose discretisation error exceeds RATIO σ, the largest first."""
    ratio = _ratio(grid, sigma)
    return [int(i) for i in np.argsort(-np.nan_to_num(ratio, nan=-1.0)) if np.isfinite(ratio[i]) and ratio[i] > RATIO]


def missing(grid: GridError, sigma: np.ndarray) -> list[str]:
    """The command's warning where no row has an estimate, and why."""
    return [] if np.isfinite(_ratio(grid, sigma)).any() else [f"no error bars at the optimum: {'; '.join(grid.said)}"]


def text(grid: GridError, plan, sigma: np.ndarray) -> str:
    """calibration.md's paragraph: the rows whose discretisation error exceeds RATIO σ, in words."""
    ratio = _ratio(grid, sigma)
    rows = plan.measurements
    head = ("Discretisation error at the optimum (`--error-estimate`, docs/accuracy.md 'Calibrations and the "
            "grid's error'): ")
    if not np.isfinite(ratio).any():
        return head + "not estimated: " + "; ".join(grid.said) + "\n"
    over = exceeding(grid, sigma)
    if not over:
        largest = int(np.nanargmax(ratio))
        return (head + f"below {RATIO:g} σ on every row (largest {number(ratio[largest], 2)} σ, "
                f"{_row(rows[largest])}): the grid does not bias the fit at this noise.\n")
    named = "; ".join(f"{_row(rows[i])}: {number(grid.errors[i], 3)} against σ {number(sigma[i], 3)} "
                      f"({number(ratio[i], 2)} σ)" for i in over[:8])
    return (head + f"above {RATIO:g} σ on {len(over)} of {np.isfinite(ratio).sum()} rows ({named}"
            f"{'; ...' if len(over) > 8 else ''}). On those rows the fit reflects the grid, not only the data: the "
            "simulations' own error is comparable to the measurements' noise, so parameters and intervals may be "
            "biased; refine the grid (biostudy convergence SCENE --target-error) or treat the result as "
            "provisional.\n")


def _row(m) -> str:
    where = f", condition {m.condition}" if m.condition else ""
    return f"line {m.line} ({m.observable} at {number(m.time)}{where})"
