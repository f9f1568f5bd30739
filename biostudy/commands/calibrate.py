"""`biostudy calibrate FILE.toml`: parameter values from measurements, with honest uncertainty.

Every simulation goes through the sweep machinery (`execution.jobs.run_jobs`): a
case file under DIR/cases/ per condition and parameter point, reused by its
fingerprint, so a re-run or a resumed calibration never repeats one; a failed
simulation is recorded and counts as a penalty in the fit.  The fit itself is
`fitting.estimate.least_squares` (multi-start, finite-difference Jacobians of
k + 1 runs a round, profile likelihoods); with method "posterior" then
`fitting.posterior.posterior` (a GP surrogate trained on a design around the
estimate, its held-out error measured, emcee on it), whose design and held-out
runs go through the same `Simulations.evaluate`; `reports.calibration` writes
DIR/calibration.nc and calibration.md, `plots.calibration` the pictures.  DIR
belongs to this calibration (`targets.owned`: locked, owned).  `load` and
`Calibrate.run` take keyword-only options, so a Python API can wrap them.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.stats import qmc

from ..data import case_files, claims, reading, writing
from ..errors import BadInput, Failed
from ..execution.backends import Kept
from ..execution.jobs import Execution, Job, run_jobs
from ..execution.ownership import Owner
from ..execution.targets import owned
from ..fitting.estimate import least_squares
from ..fitting.posterior import Options, posterior
from ..inputs import bundled
from ..inputs.keys import id_text
from ..inputs.scene import overrides_text
from ..plans import calibration_cost
from ..plans.calibration import SCENE, CalibrationPlan, label, load_calibration
from ..plots.calibration import corner_figure, fit_figure, profiles_figure
from ..plots.style import save
from ..quantities import alerts, observables, substratum
from ..reports.calibration import dataset, table_text
from .finished import Finished

# Relative noise of the sub-cell observables under tiny parameter changes: jumps when a discrete event of the
# solver moves (a cell joining the front band), measured up to 1e-4 (biomass) and 1e-3 (max_thickness) on the agar
# colony (docs/calibration.md).  The finite-difference steps are chosen against it (`fitting.least_squares`).
MODEL_NOISE = 1e-3
DESIGN_MARGIN = 0.05  # the starts' Latin hypercube fills [0.05, 0.95] of every range


@dataclass
class Simulations:
    """The calibration's simulations: points of the unit cube -> weighted residuals, through `run_jobs`."""

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
    evaluated: dict[tuple, tuple[np.ndarray, np.ndarray | None]] = field(default_factory=dict)  # point -> residuals
    seconds_running: float = 0.0
    seconds_reading: float = 0.0

    def __post_init__(self):
        rows = self.plan.measurements
        self.data = np.array([m.value for m in rows])
        self.sigma = np.array([m.sigma for m in rows])
        self.rows = {c: [i for i, m in enumerate(rows) if (m.condition or SCENE) == c] for c in self.plan.conditions}

    def job(self, condition: str, values: dict[str, float]) -> Job:
        own = [p for p in self.plan.parameters if condition in p.conditions]
        job_id = "_".join([label(condition), *(f"{p.label}={id_text(values[p.name])}" for p in own)])
        scene = self.plan.scene_at(condition, values)
        return Job(job_id, scene, self.plan.plan.scene_file, overrides_text(self.plan.overrides(condition, values)),
                   {"case_id": job_id, "calibration_file": str(self.plan.file.resolve()), "condition": condition})

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
                self.models[job.id] = self._model(job, report.failed.get(job.id))
            self.seconds_reading += time.perf_counter() - began
        out = []
        for jobs in wanted:
            model = np.full(len(self.data), np.nan)
            for condition, job in zip(self.plan.conditions, jobs):
                values = self.models[job.id]
                if values is not None:
                    model[self.rows[condition]] = values
            out.append(None if np.isnan(model).any() else (model - self.data) / self.sigma)
        for point, result in zip(points, out):
            self.evaluated.setdefault(tuple(np.round(point, 15)), (np.array(point), result))
        return out

    def model_at(self, point: np.ndarray) -> np.ndarray:
        """The model at every measurement (NaN where its simulation failed), from the runs already made."""
        model = np.full(len(self.data), np.nan)
        for condition in self.plan.conditions:
            values = self.models.get(self.job(condition, self.plan.values(point)).id)
            if values is not None:
                model[self.rows[condition]] = values
        return model

    def _model(self, job: Job, failure: str | None) -> np.ndarray | None:
        """A finished simulation's observables at its condition's measurements; None (and why, in `failed`)
        for a failed one or an observable that is NaN there."""
        if failure is not None:
            self.failed[job.id] = failure
            return None
        ds = reading.open_dataset(case_files.case_file(self.directory, job.id))
        ds.attrs.update(job.scene.substratum_attrs())  # as the scene says now
        condition = str(job.attrs["condition"])
        rows = self.rows[condition]
        series = {name: observables.evaluate(ds, name).values
                  for name in dict.fromkeys(self.plan.measurements[i].observable for i in rows)}
        times = ds["time"].values
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

    def noise(self) -> np.ndarray:
        """Per measurement, the smallest model change that is not noise, in residual units: one cell for an
        observable that counts cells, else `MODEL_NOISE` of the measured value."""
        noise = MODEL_NOISE * np.abs(self.data)
        for i, m in enumerate(self.plan.measurements):
            observable = observables.get(m.observable)
            if observable.granularity is not None:
                grid = self.plan.plan.scenes[m.condition or SCENE].grid
                step = observable.granularity(grid.spacing, len(grid.shape))
                noise[i] = max(noise[i], step)
                said = (f"{m.observable} counts cells: it moves in steps of {step:g} as a parameter changes, so its "
                        "finite differences are coarse; fit a sub-cell observable (biomass, mean_thickness) instead")
                if said not in self.warned:
                    self.warned.append(said)
            elif m.observable in substratum.QUANTITIES and \
                    self.plan.plan.scenes[m.condition or SCENE].substratum.estimator == "voxel":
                said = (f"{m.observable} is counted on voxels ([substratum] estimator = \"voxel\"): it moves in steps "
                        "of one voxel as a parameter changes, so its finite differences are coarse; the sub-cell "
                        "estimator is the one for fitting (docs/comstat.md)")
                if said not in self.warned:
                    self.warned.append(said)
        return np.maximum(noise, 1e-12) / self.sigma


def starts(k: int, n: int, seed: int) -> np.ndarray:
    """n starts in the unit cube: a scrambled Latin hypercube over [DESIGN_MARGIN, 1 - DESIGN_MARGIN]^k."""
    design = qmc.LatinHypercube(d=k, scramble=True, rng=seed).random(n)
    return DESIGN_MARGIN + (1 - 2 * DESIGN_MARGIN) * design


@dataclass
class Calibrate:
    """A calibration, validated, nothing run yet (a `commands.finished.JobCommand`)."""

    plan: CalibrationPlan
    directory: Path
    noun: str = "simulations"

    @property
    def title(self) -> str:
        return f"calibrate {self.plan.spec.name}"

    def owner(self) -> Owner:
        return Owner("calibration", self.plan.spec.name, str(self.plan.plan.scene_file.resolve()),
                     tuple(p.name for p in self.plan.parameters))

    def reports(self) -> tuple[str, ...]:
        """The report and the pictures this calibration writes beside calibration.nc."""
        method = self.plan.spec.method
        return ("calibration.md", "calibration_fit.png", *(["calibration_profiles.png"] if method.profiles else []),
                *(["calibration_corner.png"] if method.name == "posterior" else []))

    def run(self, execution: Execution = Execution()) -> Finished:
        """Fit, write DIR/calibration.nc, calibration.md and the pictures; the table is the result's summary."""
        began = time.perf_counter()
        method = self.plan.spec.method
        said = calibration_cost.note(self.plan)
        if said and execution.notify is not None:
            execution.notify("note", "", said)
        with owned(self.directory, self.owner(), "calibration.nc", execution.force, reports=self.reports()):
            backend = _backend(execution)
            simulations = Simulations(self.plan, self.directory, execution, backend)
            try:
                design = starts(len(self.plan.parameters), method.starts, method.seed)
                found = least_squares(design, len(simulations.data), simulations.noise(), simulations.evaluate,
                                      method.profiles, backend.backend.capacity if backend is not None else 1)
                sampled = _sample(self.plan, found, simulations) if method.name == "posterior" else None
            finally:
                if backend is not None:
                    backend.end()
            cost = {"simulations": len(simulations.ran), "simulations_reused": len(simulations.reused),
                    "rounds": simulations.rounds, "wall_time": time.perf_counter() - began,
                    "wall_time_simulations": simulations.seconds_running,
                    "wall_time_reading": simulations.seconds_reading}
            if sampled is not None:
                cost["wall_time_sampling"] = sampled.seconds
            ds = dataset(self.plan, found, design, simulations.model_at(found.best.x), cost, simulations.failed,
                         simulations.raised, sampled)
            table = table_text(ds)
            writing.write_atomic(ds, self.directory / "calibration.nc")
            claims.write_report(self.directory / "calibration.md", table)
            save(fit_figure(ds), self.directory / "calibration_fit.png")
            if method.profiles:
                save(profiles_figure(ds), self.directory / "calibration_profiles.png")
            if sampled is not None:
                save(corner_figure(ds), self.directory / "calibration_corner.png")
        warnings = list(simulations.warned)
        if sampled is not None:
            warnings += sampled.verdicts
        warnings += alerts.summaries(simulations.raised, "of its simulations")
        if simulations.failed:
            warnings.append(f"{len(simulations.failed)} simulations failed and counted as penalties: "
                            + "; ".join(f"{k}: {v}" for k, v in list(simulations.failed.items())[:2]))
        summary = (f"{len(simulations.ran)} simulations run, {len(simulations.reused)} reused (finished before); "
                   f"wrote {self.directory / 'calibration.nc'}, {', '.join(self.reports())}")
        return Finished(summary, {}, len(simulations.ran) + len(simulations.reused), table, self.noun, warnings,
                        result=ds)


def _sample(plan: CalibrationPlan, found, simulations: Simulations):
    """The posterior on a surrogate around the least-squares estimate (`fitting.posterior`); its design and
    held-out simulations go through `simulations` like every other."""
    method = plan.spec.method
    options = Options(method.design, method.held_out, method.walkers, method.steps, method.box, method.seed)
    began = time.perf_counter()
    running = simulations.seconds_running + simulations.seconds_reading
    try:
        sampled = posterior(simulations.evaluate, found.best.x, found.local.standard_error,
                            list(simulations.evaluated.values()), options, [p.name for p in plan.parameters])
    except ValueError as error:
        raise Failed(f"the posterior's surrogate could not be trained: {error} (the failed simulations under "
                     "cases/ say why)") from None
    sampled.seconds = (time.perf_counter() - began) - (simulations.seconds_running + simulations.seconds_reading
                                                       - running)
    if sampled.failed:
        sampled.verdicts.append(f"{sampled.failed} of the posterior's design and held-out simulations failed: left "
                                "out of the surrogate's training and of its held-out error")
    return sampled


def _backend(execution: Execution) -> Kept | None:
    """The calibration's workers, started once for all its rounds (None: here, one simulation at a time)."""
    if execution.scheduler or execution.scheduler_file:
        from ..execution.dask import DaskCluster  # lazily: Dask only when a cluster is asked for

        return Kept(DaskCluster(execution.scheduler, scheduler_file=execution.scheduler_file))
    if execution.workers:
        from ..execution.pool import LocalPool  # lazily: workers only when asked for

        return Kept(LocalPool(execution.workers))
    return None


def load(calibration: str | Path, *, output: Path | None = None,
         overrides: tuple[str, ...] | list[str] = (), runs_here: bool = False) -> Calibrate:
    """Read and validate a calibration file (a path or a bundled name), its scene, conditions and measurements;
    bad input is `BadInput` (`runs_here`: as for `commands.sweep.load`)."""
    plan = load_calibration(bundled.resolve(calibration), overrides, runs_here)
    too_costly = calibration_cost.problems(plan, runs_here)
    if too_costly:
        raise BadInput.every(too_costly)
    return Calibrate(plan, Path(output) if output is not None else Path(plan.spec.name))
