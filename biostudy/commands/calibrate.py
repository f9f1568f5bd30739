"""`biostudy calibrate FILE.toml`: parameter values from measurements, with honest uncertainty.

The calibration's `[method]` is a `fitting.methods` method; it sees the simulations only through the
`Objective` of an `execution.evaluator.Evaluator` (points of the unit cube -> weighted residuals, every
simulation a case file under DIR/cases/, reused by its fingerprint, so a re-run or a resumed calibration never
repeats one).  The method's one `Result` becomes DIR/calibration.nc and calibration.md (`reports.calibration`)
and the pictures (`plots.calibration`), and PEtab's simulation table simulation.tsv (`reports.petab`: a TSV
carries no mark, so calibration.nc records its sha256, `claims.digested`).  DIR belongs to this calibration
(`targets.owned`: locked, owned).
`load` and `Calibrate.run` take keyword-only options, so a Python API can wrap them.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..data import claims, reading, writing
from ..errors import BadInput, Failed
from ..execution.backends import Kept
from ..execution.evaluator import Evaluator
from ..execution.jobs import Execution
from ..execution.ownership import Owner
from ..execution.targets import owned
from ..fitting.methods import Result
from ..fitting.posterior import Untrainable
from ..inputs import bundled
from ..inputs.resources import Preflight
from ..plans import calibration_cost
from ..plans.calibration import CalibrationPlan, load_calibration
from ..plots.calibration import corner_figure, fit_figure, profiles_figure
from ..plots.style import save
from ..quantities import alerts
from ..reports.calibration import dataset, table_text
from ..reports.petab import simulation_table
from .finished import Finished

PICTURES = {"profiles": ("calibration_profiles.png", profiles_figure),  # per method product: file, figure
            "posterior": ("calibration_corner.png", corner_figure)}
SIMULATIONS = "simulation.tsv"  # PEtab's simulation table


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
        return Owner("calibration", self.plan.spec.name, str(self.plan.scene_file.resolve()),
                     tuple(p.name for p in self.plan.parameters))

    def reports(self) -> tuple[str, ...]:
        """The report and the pictures this calibration writes beside calibration.nc."""
        products = self.plan.spec.method.method().products
        return ("calibration.md", "calibration_fit.png", *(PICTURES[p][0] for p in products))

    def run(self, execution: Execution = Execution()) -> Finished:
        """Fit, write DIR/calibration.nc, calibration.md, the pictures and simulation.tsv; the table is the
        result's summary."""
        began = time.perf_counter()
        method = self.plan.spec.method.method()
        said = calibration_cost.note(self.plan)
        if said and execution.notify is not None:
            execution.notify("note", "", said)
        with owned(self.directory, self.owner(), "calibration.nc", execution.force, reports=self.reports(),
                   digested=(SIMULATIONS,)):
            backend = _backend(execution)
            runs = Evaluator(self.plan, self.directory, execution, backend)
            try:
                result = method(runs.objective())
            except Untrainable as error:
                raise Failed(f"the posterior's surrogate could not be trained: {error} (the failed simulations "
                             "under cases/ say why)") from None
            finally:
                if backend is not None:
                    backend.end()
            ds = dataset(self.plan, result, runs.model_at(result.estimate.best.x), self._cost(runs, result, began),
                         runs.failed, runs.raised)
            table, simulations = table_text(ds), simulation_table(ds)
            before = reading.attributes(self.directory / "calibration.nc")  # what proves simulation.tsv biostudy's
            present = claims.sha256(self.directory / SIMULATIONS)
            ds.attrs.update(claims.digested(SIMULATIONS, simulations,
                                            present if present in claims.recorded(before, SIMULATIONS) else ""))
            writing.write_atomic(ds, self.directory / "calibration.nc")
            claims.write_report(self.directory / "calibration.md", table)
            save(fit_figure(ds), self.directory / "calibration_fit.png")
            for product in method.products:
                name, figure = PICTURES[product]
                save(figure(ds), self.directory / name)
            claims.write_digested(self.directory / SIMULATIONS, simulations, before, "calibration.nc")
        summary = (f"{len(runs.ran)} simulations run, {len(runs.reused)} reused (finished before); "
                   f"wrote {self.directory / 'calibration.nc'}, {', '.join(self.reports())}, {SIMULATIONS}")
        return Finished(summary, {}, len(runs.ran) + len(runs.reused), table, self.noun, _warnings(runs, result),
                        result=ds)

    @staticmethod
    def _cost(runs: Evaluator, result: Result, began: float) -> dict[str, float]:
        cost = {**runs.cost(), "wall_time": time.perf_counter() - began}
        if result.posterior is not None:
            cost["wall_time_sampling"] = result.posterior.seconds
        return cost


def _warnings(runs: Evaluator, result: Result) -> list[str]:
    """What the run and the method say the user must know: coarse observables, the posterior's verdicts, the
    simulations' alerts, failed simulations."""
    warnings = list(runs.warned)
    if result.posterior is not None:
        warnings += result.posterior.verdicts
    warnings += alerts.summaries(runs.raised, "of its simulations")
    if runs.failed:
        warnings.append(f"{len(runs.failed)} simulations failed and counted as penalties: "
                        + "; ".join(f"{k}: {v}" for k, v in list(runs.failed.items())[:2]))
    return warnings


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
    plan = load_calibration(bundled.resolve(calibration), overrides, Preflight(runs=runs_here))
    too_costly = calibration_cost.problems(plan, runs_here)
    if too_costly:
        raise BadInput.every(too_costly)
    return Calibrate(plan, Path(output) if output is not None else Path(plan.spec.name))
