"""A calibration's simulations as the fit sees them: points of the unit cube in, weighted residuals out.

Every point is one job per condition (`execution.jobs.run_jobs`): a case file under DIR/cases/ named by its
condition and parameter values, reused by its fingerprint, so a re-run or a resumed calibration never repeats one;
a batch of points is one call of `run_jobs`, which hands its new jobs to the workers or the Dask cluster at once.
The observables a job's rows measure come back in its worker's record (`worker.Outcome.series`); only a reused
case file is read, for those observables alone.  A
failed simulation, or an observable that is NaN where it is measured, is recorded and answered with None (a penalty
in the fit).  Rows whose σ is estimated are divided by a fixed scale instead of σ (`noise`; the
objective's likelihood profiles σ out).  `Evaluator.noise` is the observables' own resolution in residual units,
which the finite-difference steps are chosen against (`fitting.least_squares`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data import case_files, netcdf, netcdf_io
from ..execution.backends import Kept
from ..execution.jobs import Execution, Job, run_jobs
from ..fitting.objective import Objective
from ..inputs.keys import id_text
from ..inputs.scene import overrides_text
from ..quantities import observables, substratum
from .noise import divisors, likelihood
from .problem import CalibrationPlan
from .spec import SCENE, label

# Relative noise of the sub-cell observables under tiny parameter changes: jumps when a discrete event of the
# solver moves (a cell joining the front band), measured on the agar colony (docs/calibration.md).
MODEL_NOISE = 1e-3


@dataclass
class Evaluator:
    """The calibration's simulations: batches of points of the unit cube -> weighted residuals, through `run_jobs`
    (each point a job per condition, its case file reused by its fingerprint); what ran, was reused, failed or
    raised an alert, and the wall time spent running and reading."""

    plan: CalibrationPlan
    directory: Path
    execution: Execution
    backend: Kept | None = None
    models: dict[str, np.ndarray | None] = field(default_factory=dict)  # job id -> model at its rows (None: failed)
    ran: list[str] = field(default_factory=list)
    reused: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    raised: dict[str, dict[str, str]] = field(default_factory=dict)  # `quantities.alerts`: attribute -> id
    warned: list[str] = field(default_factory=list)
    rounds: int = 0
    seconds_running: float = 0.0
    seconds_reading: float = 0.0

    def __post_init__(self):
        rows = self.plan.measurements
        self.data = np.array([m.value for m in rows])
        self.sigma = divisors(rows, self.plan.noise)  # σ, or a fixed scale where σ is estimated
        self.rows = {c: [i for i, m in enumerate(rows) if (m.condition or SCENE) == c] for c in self.plan.conditions}

    def job(self, condition: str, values: dict[str, float]) -> Job:
        own = [p for p in self.plan.parameters if condition in p.conditions]
        job_id = "_".join([label(condition), *(f"{p.label}={id_text(values[p.name])}" for p in own)])
        scene = self.plan.scene_at(condition, values)
        measured = tuple(dict.fromkeys(self.plan.measurements[i].observable for i in self.rows[condition]))
        return Job(job_id, scene, self.plan.scene_file, overrides_text(self.plan.overrides(condition, values)),
                   {"case_id": job_id, "calibration_file": str(self.plan.file.resolve()), "condition": condition},
                   measure=measured)

    def evaluate(self, points: list[np.ndarray]) -> list[np.ndarray | None]:
        """The weighted residuals (model - measurement) / sigma at every point; None where a simulation failed."""
        wanted = [[self.job(c, self.plan.values(p)) for c in self.plan.conditions] for p in points]
        new = {job.id: job for jobs in wanted for job in jobs if job.id not in self.models}
        if new:
            began = time.perf_counter()
            report = run_jobs(list(new.values()), self.directory, self.execution, backend=self.backend)
            self.seconds_running += time.perf_counter() - began
            self.rounds += 1
            self.ran += report.ran
            self.reused += report.skipped
            for name, cases in report.alerts.items():
                self.raised.setdefault(name, {}).update(cases)
            began = time.perf_counter()
            for job in new.values():
                self.models[job.id] = self._model(job, report.failed.get(job.id), report.series.get(job.id))
            self.seconds_reading += time.perf_counter() - began
        out = []
        for jobs in wanted:
            model = np.full(len(self.data), np.nan)
            for condition, job in zip(self.plan.conditions, jobs):
                values = self.models[job.id]
                if values is not None:
                    model[self.rows[condition]] = values
            out.append(None if np.isnan(model).any() else (model - self.data) / self.sigma)
        return out

    def model_at(self, point: np.ndarray) -> np.ndarray:
        """The model at every measurement (NaN where its simulation failed), from the runs already made."""
        model = np.full(len(self.data), np.nan)
        for condition in self.plan.conditions:
            values = self.models.get(self.job(condition, self.plan.values(point)).id)
            if values is not None:
                model[self.rows[condition]] = values
        return model

    def _model(self, job: Job, failure: str | None, series: dict | None) -> np.ndarray | None:
        """A finished simulation's observables at its condition's measurements (`series`: its worker's record, or
        None: read from its reused case file); None (and why, in `failed`) for a failed one or an observable that
        is NaN there."""
        if failure is not None:
            self.failed[job.id] = failure
            return None
        series = series if series is not None else self._recorded(job)
        rows = self.rows[str(job.attrs["condition"])]
        times = series["time"]
        values = []
        for i in rows:
            index = int(np.argmin(np.abs(times - self.plan.times[i])))
            value = float(series[self.plan.measurements[i].observable][index])
            if not np.isfinite(value):
                self.failed[job.id] = (f"{self.plan.measurements[i].observable} is {value} at T* = "
                                       f"{times[index]:.4g} (line {self.plan.measurements[i].line} of the table)")
                return None
            values.append(value)
        return np.array(values)

    def _recorded(self, job: Job) -> dict[str, np.ndarray]:
        """The time and the observables `job.measure` of its reused case file: those it holds, measured on the
        substratum its scene says now (else computed from its fields, as they are then)."""
        with netcdf_io.open_dataset(case_files.case_file(self.directory, job.id)) as opened:
            ds = observables.as_measured(netcdf.as_run(opened), job.scene.substratum_attrs())
            series = {"time": ds["time"].values}
            for name in job.measure:
                series[name] = (ds[name] if name in ds else observables.evaluate(ds, name)).values
        return series

    def noise(self) -> np.ndarray:
        """Per measurement, the smallest model change that is not noise, in residual units: one cell for an
        observable that counts cells, else `MODEL_NOISE` of the measured value."""
        noise = MODEL_NOISE * np.abs(self.data)
        for i, m in enumerate(self.plan.measurements):
            observable = observables.get(m.observable)
            if observable.granularity is not None:
                grid = self.plan.scenes[m.condition or SCENE].grid
                step = observable.granularity(grid.spacing, len(grid.shape))
                noise[i] = max(noise[i], step)
                said = (f"{m.observable} counts cells: it moves in steps of {step:g} as a parameter changes, so its "
                        "finite differences are coarse; fit a sub-cell observable (biomass, mean_thickness) instead")
                if said not in self.warned:
                    self.warned.append(said)
            elif m.observable in substratum.QUANTITIES and \
                    self.plan.scenes[m.condition or SCENE].substratum.estimator == "voxel":
                said = (f"{m.observable} is counted on voxels ([substratum] estimator = \"voxel\"): it moves in steps "
                        "of one voxel as a parameter changes, so its finite differences are coarse; the sub-cell "
                        "estimator is the one for fitting (docs/comstat.md)")
                if said not in self.warned:
                    self.warned.append(said)
        return np.maximum(noise, 1e-12) / self.sigma


    def objective(self) -> Objective:
        """The fit's view of these simulations (`fitting.objective`)."""
        workers = self.backend.backend.capacity if self.backend is not None else 1
        return Objective(self.evaluate, len(self.data), self.noise(), tuple(p.name for p in self.plan.parameters),
                         workers, likelihood=likelihood(self.plan.noise))

    def cost(self) -> dict[str, float]:
        """What the simulations cost: counts and wall times (calibration.nc's attributes)."""
        return {"simulations": len(self.ran), "simulations_reused": len(self.reused), "rounds": self.rounds,
                "wall_time_simulations": self.seconds_running, "wall_time_reading": self.seconds_reading}
