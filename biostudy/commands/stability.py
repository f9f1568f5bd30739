"""`biostudy stability CATALOGUE`: stiff and extreme cases, each judged (`reports.stability`).

Writes DIR/cases/, DIR/stability.nc and DIR/stability.md; a case that neither
completes within its bounds nor stops with the mechanics' diagnosis fails.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from ..data import claims, provenance, writing
from ..execution.jobs import Execution, SweepReport, plan_jobs, plan_owner, run_jobs
from ..execution.targets import owned
from ..inputs import bundled
from ..inputs.resources import Preflight
from ..plans import catalogue as catalogues
from ..plans.cases import Plan
from ..reports.stability import table_text, verdicts
from .finished import Finished

REPORT = "stability.md"


def run_catalogue(plan: Plan, directory: Path, execution: Execution = Execution()) -> tuple[xr.Dataset, SweepReport]:
    """Run a loaded catalogue, judge every case, write DIR/stability.nc (DIR: `targets.owned`)."""
    jobs = plan_jobs(plan, catalogue_file=str(plan.file.resolve()))
    with owned(directory, plan_owner(plan, "catalogue"), "stability.nc", execution.force, reports=(REPORT,)):
        report = run_jobs(jobs, directory, execution)
        ds = verdicts(jobs, directory)
        ds.attrs = provenance.with_provenance({
            "Conventions": "CF-1.10", "title": f"stability catalogue: {plan.spec.name}",
            "catalogue": plan.file.read_text(encoding="utf-8"), "catalogue_file": str(plan.file.resolve()),
            "scene_file": str(plan.scene_file.resolve()), "cases": len(jobs), "cases_ok": int(ds["ok"].sum())})
        writing.write_atomic(ds, Path(directory) / "stability.nc")
    return ds, report


@dataclass
class Stability:
    plan: Plan
    path: Path
    directory: Path
    noun: str = "cases"

    @property
    def title(self) -> str:
        return f"stability {self.path.stem}"

    @property
    def summary(self) -> Path:
        return self.directory / "stability.nc"

    def run(self, execution: Execution) -> Finished:
        ds, report = run_catalogue(self.plan, self.directory, execution)
        table = table_text(ds)
        claims.write_report(self.directory / REPORT, table)
        failed = {str(c): str(m) for c, m, ok in zip(ds.case.values, ds.message.values, ds.ok.values) if not ok}
        return Finished(f"wrote {self.directory / 'stability.nc'} and stability.md: {int(ds.ok.sum())} of "
                        f"{ds.sizes['case']} cases completed within bounds or stopped with a diagnosis",
                        failed, ds.sizes["case"], table, warnings=report.warnings(), result=ds)


def load(catalogue: str | Path, *, directory: Path | None = None,
         set: list[str] | tuple[str, ...] = (), runs_here: bool = False) -> Stability:  # noqa: A002
    """Read and validate a catalogue (a path or a bundled name) and every case with the overrides `set` (the
    options: `declared.STABILITY`); bad input is `BadInput` (`runs_here`: as for `commands.sweep.load`)."""
    path = bundled.resolve(catalogue)
    return Stability(catalogues.load(path, set, Preflight(runs=runs_here)), path,
                     Path(directory) if directory is not None else Path(f"{path.stem}-results"))
