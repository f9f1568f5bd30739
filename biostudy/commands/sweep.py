"""`biostudy sweep STUDY`: every case of a study to DIR/cases/<id>.nc, combined into DIR/study.nc.

Re-running skips finished cases (`execution.jobs.run_jobs`); the directory
belongs to one study (`execution.targets.owned`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from ..data import combine
from ..execution.jobs import Execution, SweepError, SweepReport, plan_jobs, plan_owner, run_jobs
from ..execution.targets import owned
from ..inputs import bundled
from ..plans.cases import Plan
from ..plans.study import load_study
from .finished import Finished


def run_study(plan: Plan, directory: str | Path, execution: Execution = Execution()) -> SweepReport:
    """Run every case not yet recorded, write DIR/cases/<id>.nc for each and DIR/study.nc (see `run_jobs`);
    the directory must be this study's (or new, or `execution.force`) and not in use by another run."""
    layouts = combine.case_layouts(plan)
    jobs = [replace(job, layout=layouts[job.id]) for job in plan_jobs(plan, study_file=str(plan.file.resolve()))]
    with owned(directory, plan_owner(plan, "study"), "study.nc", execution.force):
        report = run_jobs(jobs, directory, execution)
        try:
            combine.write_study(plan, Path(directory))
        except OSError as error:  # `store.NotWritten`, e.g. a full disk
            raise SweepError(f"{error}; the case files in {Path(directory) / 'cases'} are kept: run the same "
                             "command again to write study.nc (nothing is computed again)") from None
    return report


@dataclass
class Sweep:
    plan: Plan
    directory: Path
    noun: str = "cases"

    @property
    def title(self) -> str:
        return self.plan.spec.name

    def run(self, execution: Execution) -> Finished:
        report = run_study(self.plan, self.directory, execution)
        return Finished(f"{len(report.ran)} cases run, {len(report.skipped)} skipped (finished before), "
                        f"{len(report.failed)} failed; wrote {report.study}", report.failed, len(self.plan.cases),
                        warnings=report.warnings(), result=report)


def load(study: str | Path, *, output: Path | None = None, overrides: tuple[str, ...] | list[str] = ()) -> Sweep:
    """Read and validate a study (a path or a bundled name) and every case; bad input is `BadInput`."""
    plan = load_study(bundled.resolve(study), overrides)
    return Sweep(plan, Path(output) if output is not None else Path(plan.spec.name))
