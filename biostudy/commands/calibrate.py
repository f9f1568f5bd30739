"""`biostudy calibrate FILE.toml`: parameter values from measurements, with honest uncertainty.

The calibration (`biostudy.calibration`) is read into a plan (`calibration.problem`); its `[method]` is a
`calibration.methods` method, which sees the simulations only through the `Objective` of a
`calibration.evaluator.Evaluator` (points of the unit cube -> weighted residuals, every simulation a case file
under DIR/cases/, reused by its fingerprint, so a re-run or a resumed calibration never repeats one).  The
method's one `Result` becomes DIR/calibration.nc and calibration.md (`calibration.report`), the pictures the
method declares (`Method.pictures`), PEtab's simulation table simulation.tsv (`calibration.petab`: a TSV
carries no mark, so calibration.nc records its sha256, `claims.digested`) and the calibration as a PEtab problem in
DIR/petab/ (`calibration.petab_out`; its files proven the same way).  DIR belongs to this calibration
(`targets.owned`: locked, owned).
`load` and `Calibrate.run` take keyword-only options, so a Python API can wrap them.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..calibration import cost, grid_error, petab_out
from ..calibration.evaluator import Evaluator
from ..calibration.methods import FIT, Method, Result, chosen
from ..calibration.petab import simulation_table
from ..calibration.problem import CalibrationPlan, load_calibration
from ..calibration.report import dataset, table_text
from ..data import claims, reading, writing
from ..errors import BadInput
from ..execution.backends import Kept
from ..execution.jobs import Execution, backend
from ..execution.ownership import Owner
from ..execution.targets import owned
from ..inputs import bundled
from ..inputs.resources import Preflight
from ..plots.style import save
from ..quantities import alerts
from .finished import Finished

SIMULATIONS = "simulation.tsv"  # PEtab's simulation table


@dataclass
class Calibrate:
    """A calibration, validated, nothing run yet (a `commands.finished.JobCommand`)."""

    plan: CalibrationPlan
    directory: Path
    noun: str = "simulations"
    error_estimate: bool = False  # the discretisation error at the optimum against σ (`calibration.grid_error`)

    @property
    def title(self) -> str:
        return f"calibrate {self.plan.spec.name}"

    @property
    def summary(self) -> Path:
        return self.directory / "calibration.nc"

    def owner(self) -> Owner:
        return Owner("calibration", self.plan.spec.name, str(self.plan.scene_file.resolve()),
                     tuple(p.name for p in self.plan.parameters))

    def reports(self) -> tuple[str, ...]:
        """The report and the pictures this calibration writes beside calibration.nc."""
        return ("calibration.md", FIT.file, *(p.file for p in chosen(self.plan.spec.method).pictures()))

    def run(self, execution: Execution = Execution()) -> Finished:
        """Fit, write DIR/calibration.nc, calibration.md, the pictures and simulation.tsv; the table is the
        result's summary."""
        began = time.perf_counter()
        method = chosen(self.plan.spec.method)
        if not (execution.scheduler or execution.scheduler_file):  # local workers: as many simulations at once
            crowded = cost.workers_problem(self.plan, execution.workers)
            if crowded is not None:
                raise crowded
        said = cost.note(self.plan)
        if said and execution.notify is not None:
            execution.notify("note", "", said)
        with owned(self.directory, self.owner(), "calibration.nc", execution.force, reports=self.reports(),
                   digested=(SIMULATIONS, *(f"{petab_out.FOLDER}/{name}" for name in petab_out.NAMES))):
            backend = _backend(execution)
            runs = Evaluator(self.plan, self.directory, execution, backend)
            grid = None
            try:
                result = method(runs.objective())
                if self.error_estimate:
                    grid = grid_error.at_optimum(runs, result.estimate.best.x)
            finally:
                if backend is not None:
                    backend.end()
            ds = dataset(self.plan, result, runs.model_at(result.estimate.best.x),
                         {**runs.cost(), "wall_time": time.perf_counter() - began, **method.cost(result)}, runs.failed,
                         runs.raised)
            table, simulations = table_text(ds), simulation_table(ds)
            if grid is not None:
                sigma = ds["sigma"].values
                ds = ds.assign(grid_error.variables(grid, sigma, [str(ds["measured"].attrs.get("units", "1"))]))
                said = grid_error.text(grid, self.plan, sigma)
                ds.attrs["discretisation"] = said.strip()
                table += "\n" + said
            before = reading.attributes(self.directory / "calibration.nc")  # what proves simulation.tsv biostudy's
            present = claims.sha256(self.directory / SIMULATIONS)
            ds.attrs.update(claims.digested(SIMULATIONS, simulations,
                                            present if present in claims.recorded(before, SIMULATIONS) else ""))
            problem, unwritten = _petab(self.plan, self.directory / petab_out.FOLDER)
            ds.attrs.update(petab_out.digests(problem, self.directory / petab_out.FOLDER, before))
            writing.write_atomic(ds, self.directory / "calibration.nc")
            claims.write_report(self.directory / "calibration.md", table)
            for picture in (FIT, *method.pictures()):
                save(picture.draw(ds), self.directory / picture.file)
            claims.write_digested(self.directory / SIMULATIONS, simulations, before, "calibration.nc")
            if problem:
                petab_out.write(problem, self.directory / petab_out.FOLDER, before)
        summary = (f"{len(runs.ran)} simulations run, {len(runs.reused)} reused (finished before); "
                   f"wrote {self.directory / 'calibration.nc'}, {', '.join(self.reports())}, {SIMULATIONS}"
                   + (f", {petab_out.FOLDER}/ (the PEtab problem)" if problem else ""))
        over = [] if grid is None else grid_error.exceeding(grid, ds["sigma"].values)
        biased = [f"the grid's discretisation error exceeds {grid_error.RATIO:g} σ on {len(over)} rows (calibration.md)"
                  ] if over else [] if grid is None else grid_error.missing(grid, ds["sigma"].values)
        return Finished(summary, {}, len(runs.ran) + len(runs.reused), table, self.noun,
                        [*_warnings(runs, method, result), *unwritten, *biased], result=ds)


def _warnings(runs: Evaluator, method: Method, result: Result) -> list[str]:
    """What the run and the method say the user must know: coarse observables, the method's verdicts, the
    simulations' alerts, failed simulations."""
    warnings = [*runs.warned, *method.warnings(result)]
    warnings += alerts.summaries(runs.raised, "of its simulations")
    if runs.failed:
        warnings.append(f"{len(runs.failed)} simulations failed and counted as penalties: "
                        + "; ".join(f"{k}: {v}" for k, v in list(runs.failed.items())[:2]))
    return warnings


def _petab(plan: CalibrationPlan, folder: Path) -> tuple[dict[str, str], list[str]]:
    """The PEtab problem's texts (`calibration.petab_out`), or none and why PEtab cannot hold this calibration."""
    try:
        return petab_out.problem_texts(plan, folder, plan.common), []
    except petab_out.NotPetab as error:
        return {}, [f"{folder} not written: {error}"]


def _backend(execution: Execution) -> Kept | None:
    """The calibration's workers, started once for all its rounds, where `run_jobs` would start them
    (`execution.jobs.backend`; None: here, one simulation at a time)."""
    if not (execution.workers or execution.scheduler or execution.scheduler_file):
        return None
    notify = execution.notify
    return Kept(backend(execution, None if notify is None else lambda message: notify("note", "", message)))


def load(calibration: str | Path, *, directory: Path | None = None, set: list[str] | tuple[str, ...] = (),  # noqa: A002
         error_estimate: bool = False, runs_here: bool = False) -> Calibrate:
    """Read and validate a calibration file (a path or a bundled name), its scene with the overrides `set`, its
    conditions and measurements (the options: `declared.CALIBRATE`); bad input is `BadInput` (`runs_here`: as
    for `commands.sweep.load`)."""
    plan = load_calibration(bundled.resolve(calibration), set, Preflight(runs=runs_here))
    too_costly = cost.problems(plan, runs_here)
    if too_costly:
        raise BadInput.every(too_costly)
    return Calibrate(plan, Path(directory) if directory is not None else Path(plan.spec.name),
                     error_estimate=error_estimate)
