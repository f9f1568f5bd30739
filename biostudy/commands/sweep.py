"""`biostudy sweep STUDY`: every case of a study to DIR/cases/<id>.nc, combined into DIR/study.nc.

Re-running skips finished cases (`execution.jobs.run_jobs`); the directory
belongs to one study (`execution.targets.owned`).

Array jobs without Dask (a SLURM or PBS job array; docs/clusters.md):
``--case ID`` runs the cases named; ``--task N`` alone case number N, the
fixed numbering of the study's order from 0 (an array index: resubmitting
``--array=3,5`` runs cases 3 and 5 again, nothing else); ``--task N --tasks
M`` the N-th of M shares (cases N, N + M, N + 2M, ..., so every share gets
cheap and dear cases alike; M fixed by the user, never the array's size, so
that share N is the same cases whichever indices are submitted).  Such tasks hold the directory's lock
shared (`ownership`): any number of them write their own case files into
one directory at once, none removes another's temporary file (another node's
writer is alive though its process id is not here), and none writes
study.nc.  ``--combine`` (or an ordinary run of the whole study, which runs
what is missing) then writes study.nc from the case files there.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from ..data import case_files, combine, netcdf_io
from ..errors import BadInput
from ..execution import case_errors
from ..execution.jobs import Execution, SweepError, SweepReport, plan_jobs, plan_owner, run_jobs
from ..execution.targets import owned
from ..inputs import bundled
from ..inputs.resources import Preflight
from ..plans.cases import Plan
from ..plans.study import load_study
from .finished import Finished


@dataclass(frozen=True)
class Share:
    """Which cases an array task runs: those named, case number `task` (from 0, in the study's order), or with
    `tasks` the `task`-th of `tasks` shares."""

    cases: tuple[str, ...] = ()
    task: int | None = None
    tasks: int | None = None

    def describe(self) -> str:
        if self.cases:
            return f"cases {', '.join(self.cases)}"
        return f"case number {self.task}" if self.tasks is None else f"share {self.task} of {self.tasks}"


def choose(plan: Plan, share: Share) -> list[str]:
    """The ids of the cases `share` runs; `BadInput` for a case the study does not have or a task out of range."""
    ids = [case.id for case in plan.cases]
    if share.cases:
        unknown = [c for c in share.cases if c not in ids]
        if unknown:
            listed = ", ".join(ids[:4]) + (", ..." if len(ids) > 4 else "")
            raise BadInput(f"no case {unknown[0]!r} in this study (its {len(ids)} cases: {listed})", "--case")
        return [i for i in ids if i in share.cases]
    if share.task is None:
        raise BadInput("needs --task N (share N of M, N from 0 to M - 1)", "--tasks")
    if share.tasks is None:
        if not 0 <= share.task < len(ids):
            raise BadInput(f"no case number {share.task} in this study (its {len(ids)} cases are numbered 0.."
                           f"{len(ids) - 1} in the study's order)", "--task")
        return [ids[share.task]]
    if not 0 <= share.task < share.tasks:
        raise BadInput(f"must be in 0..{share.tasks - 1} for --tasks {share.tasks} (got {share.task})", "--task")
    return ids[share.task::share.tasks]


def run_study(plan: Plan, directory: str | Path, execution: Execution = Execution(),
              share: Share | None = None, error_estimate: bool = False) -> SweepReport:
    """Run every case not yet recorded (or, for an array task, those of its `share`), write DIR/cases/<id>.nc
    for each and, unless it is an array task, DIR/study.nc (see `run_jobs`); the directory must be this
    study's (or new, or `execution.force`) and not in use by another run (array tasks share it).
    `error_estimate`: each case's companions run too, and its file gets its error bars (`case_errors`)."""
    layouts = combine.case_layouts(plan)
    jobs = [replace(job, layout=layouts[job.id]) for job in plan_jobs(plan, study_file=str(plan.file.resolve()))]
    if share is not None:
        chosen = set(choose(plan, share))
        jobs = [job for job in jobs if job.id in chosen]
    extra, notes = case_errors.companion_jobs(jobs) if error_estimate else ([], {})
    with owned(directory, plan_owner(plan, "study"), "study.nc", execution.force, shared=share is not None):
        report = run_jobs([*jobs, *extra], directory, execution, tidy=share is None)
        if error_estimate:
            case_errors.add_error_bars(jobs, notes, directory)
        if share is None:
            write_study(plan, Path(directory))
    return report


def write_study(plan: Plan, directory: Path) -> Path:
    """DIR/study.nc from the case files; a write that fails (a full disk) says the case files are kept."""
    try:
        return combine.write_study(plan, directory)
    except OSError as error:  # `writing.NotWritten`, e.g. a full disk
        raise SweepError(f"{error}; the case files in {directory / 'cases'} are kept: run the same command again "
                         "to write study.nc (nothing is computed again)") from None


def combine_study(plan: Plan, directory: str | Path, force: bool = False) -> Path:
    """DIR/study.nc from the case files under DIR/cases/ as they are (missing cases: status "missing"),
    running nothing; the directory must be this study's.  A case file that cannot be read whole is refused,
    each one named: counted as missing, it would hide a case that was computed."""
    directory = Path(directory)
    if not (directory / "cases").is_dir():
        raise BadInput("has no cases/ directory: nothing to combine (run the study, or its array tasks, first)",
                       directory)
    with owned(directory, plan_owner(plan, "study"), "study.nc", force):
        damaged = [BadInput("damaged or truncated: it cannot be read whole (header, attributes or data); "
                            f"`biostudy sweep {plan.file} -o {directory}` without --combine computes it again", path)
                   for path in (case_files.case_file(directory, case.id) for case in plan.cases)
                   if path.exists() and not netcdf_io.intact(path)]
        if damaged:
            raise BadInput.every(damaged)
        return write_study(plan, directory)


@dataclass
class Sweep:
    plan: Plan
    directory: Path
    noun: str = "cases"
    share: Share | None = None  # an array task's cases
    combine_only: bool = False  # --combine: write study.nc from what is there
    error_estimate: bool = False  # every case's companions run too, its file given error bars

    @property
    def title(self) -> str:
        return self.plan.spec.name + (f" ({self.share.describe()})" if self.share else "")

    @property
    def summary(self) -> Path:
        return self.directory / "study.nc"

    def run(self, execution: Execution) -> Finished:
        if self.combine_only:
            written = combine_study(self.plan, self.directory, execution.force)
            statuses = _statuses(written)
            again = not_done(self.plan, written)
            rerun = (f"; cases {','.join(map(str, again))} are not done: `sbatch --array={','.join(map(str, again))}`"
                     " runs just those again as one-case array tasks (docs/clusters.md)") if again else ""
            return Finished(f"combined {len(self.plan.cases)} cases ({statuses}) into {written}{rerun}", {},
                            len(self.plan.cases), result=written)
        report = run_study(self.plan, self.directory, execution, self.share, self.error_estimate)
        companions, said = case_errors.cases_only(report)
        warnings = [*report.warnings(), *said]
        total = len(self.plan.cases) if self.share is None else len(report.ran) + len(report.skipped)
        if self.share is not None:
            return Finished(f"{len(report.ran)} cases run, {len(report.skipped)} skipped (finished before), "
                            f"{len(report.failed)} failed ({self.share.describe()}); study.nc is written by "
                            f"`biostudy sweep {self.plan.file} -o {self.directory} --combine` once every task "
                            "is done", report.failed, total, warnings=warnings, result=report)
        with_companions = f" (and {len(companions)} error-bar companions)" if companions else ""
        return Finished(f"{len(report.ran)} cases run, {len(report.skipped)} skipped (finished before), "
                        f"{len(report.failed)} failed{with_companions}; wrote {report.study}", report.failed, total,
                        warnings=warnings, result=report)


def not_done(plan: Plan, study: Path) -> list[int]:
    """The case numbers (`--task N`: the study's order from 0) whose status in `study` is not "done"."""
    import xarray as xr

    with xr.open_dataset(study) as ds:
        status = dict(zip(map(str, ds["case_id"].values.ravel()), map(str, ds["status"].values.ravel())))
    return [number for number, case in enumerate(plan.cases) if status.get(case.id, "missing") != "done"]


def _statuses(study: Path) -> str:
    from ..data.netcdf_io import opened

    with opened(study) as nc:
        return ", ".join(f"{nc.getncattr(f'cases_{s}')} {s}" for s in ("done", "failed", "missing"))


def load(study: str | Path, *, directory: Path | None = None, set: list[str] | tuple[str, ...] = (),  # noqa: A002
         cases: list[str] | tuple[str, ...] = (), task: int | None = None, tasks: int | None = None,
         combine: bool = False, error_estimate: bool = False, runs_here: bool = False) -> Sweep:
    """Read and validate a study (a path or a bundled name) and every case with the overrides `set`, and which
    cases to run (`cases`, or share `task` of `tasks`; `combine`: none; the options: `declared.SWEEP`); bad input
    is `BadInput`.  `runs_here`: the cases run on this machine, so one too big for its memory is refused by its
    estimate before its masks are made."""
    combine_only = combine
    plan = load_study(bundled.resolve(study), set, Preflight(runs=runs_here and not combine_only))
    share = None
    if cases or task is not None or tasks is not None:
        if cases and (task is not None or tasks is not None):
            raise BadInput("give --case or --task/--tasks, not both", "--case")
        share = Share(tuple(cases), task, tasks)
        choose(plan, share)  # bad input now, before anything runs
    if combine_only and share is not None:
        raise BadInput("--combine runs no case; leave out --case and --task", "--combine")
    return Sweep(plan, Path(directory) if directory is not None else Path(plan.spec.name), share=share,
                 combine_only=combine_only, error_estimate=error_estimate,
                 noun="runs" if error_estimate else "cases")  # the progress counts the companions' runs too
