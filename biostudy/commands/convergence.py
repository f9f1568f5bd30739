"""`biostudy convergence SCENE`: the scene refined in space, time, both and with error-controlled steps.

Each level is one job (`execution.jobs`: workers, a Dask cluster, resume;
identical runs, level 0 of three series, run once), measured by
`reports.convergence` into DIR/convergence.nc, convergence.md and the
work-precision picture (error against wall time).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from ..data import claims, provenance, writing
from ..errors import BadInput
from ..execution.jobs import Execution, Job, SweepReport, run_jobs
from ..execution.ownership import Owner
from ..execution.targets import owned
from ..inputs import bundled
from ..inputs.keys import apply_overrides, given_by
from ..inputs.resources import Preflight
from ..inputs.scene import Scene, overrides_text, read_scene_data, scene_from_data
from ..plans import resolution
from ..plans.refinement import check_refinable, plan, refined, with_reference
from ..plots.accuracy import work_precision
from ..reports import error_model
from ..reports.convergence import measure
from ..reports.convergence_levels import SCALARS, Level, given_reference
from ..reports.convergence_table import table_text
from .finished import Finished

REPORTS = ("convergence.md", "work_precision.png")


@dataclass
class Convergence:
    """A scene's refinement plan, validated, nothing run yet."""

    path: Path
    data: dict  # the scene's raw data with the overrides applied
    base: Scene
    levels: int
    series: tuple[str, ...]
    tolerance: float
    common: dict  # the overrides (level 0 and every level)
    directory: Path
    reference: Path | None = None  # a run every level is measured against
    given: Level | None = None  # its quantities at the scene's output times
    time: float | None = None
    target_error: float | None = None  # recommend the cheapest resolution for it (`reports.error_model`)
    observable: str = "biofilm_volume"
    noun: str = "runs"

    @property
    def title(self) -> str:
        return f"convergence {self.path.stem}"

    @property
    def summary(self) -> Path:
        return self.directory / "convergence.nc"

    def run(self, execution: Execution) -> Finished:
        ds, report = self.measure(execution)
        table = table_text(ds)
        claims.write_report(self.directory / REPORTS[0], table)
        work_precision(ds, self.directory / REPORTS[1])
        return Finished(f"wrote {self.directory / 'convergence.nc'}, convergence.md, work_precision.png "
                        f"({len(report.ran)} runs, {len(report.skipped)} finished before)", report.failed,
                        len(report.ran) + len(report.skipped), table, "runs", report.warnings(), result=ds)

    def measure(self, execution: Execution = Execution()) -> tuple[xr.Dataset, SweepReport]:
        """Run every level (skipping finished ones), measure, write DIR/convergence.nc; DIR belongs to this
        scene's convergence runs (`targets.owned`; `execution.force` takes over another's)."""
        given = self.given
        wanted = plan(self.base, self.levels, self.series, self.tolerance, reference=given is None)
        scenes = {level.job_id: refined(self.data, self.path, level) for level in wanted}
        text = overrides_text(self.common)
        jobs = [Job(job_id, scene, self.path, text, {"case_id": job_id}) for job_id, scene in scenes.items()]
        owner = Owner("convergence", self.path.stem, str(self.path.resolve()))
        with owned(self.directory, owner, "convergence.nc", execution.force, reports=REPORTS):
            report = run_jobs(jobs, self.directory, execution)
            series = self.series if given is not None else with_reference(self.series)
            ds = measure(wanted, self.directory, self.levels, series, self.base, given, self.time, scenes)
            if self.reference is not None and given is not None:
                ds.attrs["reference"] = f"the run in {Path(self.reference).resolve()}"
            if self.target_error is not None:
                ds.attrs.update(self.recommended(ds, wanted, scenes).attrs(self.observable))
            ds.attrs = provenance.with_provenance({**ds.attrs, "scene": self.base.to_toml(),
                                              "scene_file": str(self.path.resolve()), "overrides": text})
            writing.write_atomic(ds, self.directory / "convergence.nc")
        return ds, report


    def recommended(self, ds: xr.Dataset, wanted: list, scenes: dict) -> error_model.Recommendation:
        """The cheapest resolution predicted to reach `target_error` in `observable` at `time`, among the grids
        that hold the scene's regions as the finest level does."""
        finest = scenes[max(wanted, key=lambda level: level.refine).job_id]
        scheme = self.base.numerics.advection  # type: ignore[attr-defined]  # (a model made from solver.Numerics)
        fit = error_model.fit(ds, self.observable, self.time, scheme)
        resolves = resolution.resolves_like(self.base, self.path, finest)
        return error_model.recommend(fit, float(self.target_error or 0), ds, self.base.time.t_end,
                                     list(self.base.grid.shape), self.base.grid.spacing, resolves)


def load(scene: str | Path, *, levels: int, series: tuple[str, ...], tolerance: float, directory: Path | None = None,
         set: list[str] | tuple[str, ...] = (), reference: Path | None = None,  # noqa: A002
         time: float | None = None, target_error: float | None = None, observable: str = "biofilm_volume",
         runs_here: bool = False) -> Convergence:
    """Read and validate the scene with the overrides `set` (level 0's) and the plan of `levels` per `series`
    (the options, their defaults and rules: `declared.CONVERGENCE`); bad input is `BadInput` (`runs_here`: level
    0 runs here, as for `commands.sweep.load`)."""
    path = bundled.resolve(scene)
    data = read_scene_data(path)
    common = dict(apply_overrides(data, set))
    base = scene_from_data(copy.deepcopy(data), path, given_by(common, "--set"), Preflight(runs=runs_here))
    check_refinable(base, path)
    if target_error is not None and observable not in SCALARS:
        raise BadInput(f"{observable!r} is not measured by a convergence study; choose from {', '.join(SCALARS)}",
                       None, "--observable")
    directory = Path(directory) if directory is not None else Path(f"{path.stem}-convergence")
    given = None if reference is None else given_reference(reference, base)
    return Convergence(path, data, base, levels, tuple(series), tolerance, common, directory, reference, given,
                       time, target_error, observable)
