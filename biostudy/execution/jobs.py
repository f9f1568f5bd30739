"""Jobs: simulations recorded under DIR/cases/, run here, on N local processes or on a Dask cluster.

A job is one simulation of a sweep, a convergence level, a stability case or
a calibration's evaluation: a validated scene and where it came from.
`run_jobs` runs those not recorded yet and records each one (its dataset or
its failure); what is recorded is reused by its fingerprint (`identity`).

This process only schedules: a worker does all of a case's work (`worker.perform`:
the simulation, the dataset finished, its case file written atomically with
`writing.write_atomic`) and hands back a small record (`worker.Outcome`), so
this process never touches a case's fields.  A worker on a Dask cluster, which
may not see this directory, hands back the file's bytes, which this process
writes (atomically too).  Local workers and the cases run here write into the
directory this process holds (`targets.owned`), each file under a temporary
of its writer's process id until it is renamed: an interruption (Ctrl-C,
SIGTERM, a kill of this process, which ends its workers) never leaves a
half-written file under a final name, and the temporary of a worker that died
is removed when its death is seen (or by the next sweep there).

A case that fails (the solver's `SimulationError`, or any other exception
inside the simulation) is recorded as failed and the others go on.  Local
worker processes start with ``OMP_NUM_THREADS=1`` (one simulation per core;
FiPy's suite ran 40x slower with unrestricted threads) and
``FIPY_SOLVERS=scipy``; Dask's nanny sets the thread variables for its
workers itself.  What runs in a worker is in `worker`, where cases run in
`backends` (`pool`: local processes, a worker that dies takes only its own
case with it; `dask`: a cluster).  The caller claims the directory first
(`targets.owned`): locked for this process, owned by one study.
"""
from __future__ import annotations

import contextlib
import dataclasses
import errno
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import solver
from solver.output import versions

from ..data import case_files, netcdf, netcdf_io, provenance, writing
from ..data.finish import Record
from ..errors import BadInput, Failed
from ..inputs import cores, resources
from ..inputs.scene import Scene, overrides_text
from ..plans.cases import Plan
from ..quantities import alerts
from . import ownership, pool
from .backends import Backend, Here, windowed
from .dask import DaskCluster, SchedulerLost
from .identity import fingerprint, legacy_fingerprint, matches
from .pool import LocalPool
from .worker import Outcome, Simulated, Task, failure_record


class SweepError(Failed):
    """The sweep cannot go on (its workers are gone, a file cannot be written); cases finished so far are kept."""


@dataclass(frozen=True, kw_only=True)
class Execution:
    """How a job command (sweep, convergence, stability, calibrate) runs its cases: here, on `workers` local
    processes or on the Dask `scheduler` (its address, or the `scheduler_file` it wrote); which finished cases
    it runs again; whether it may take over a directory of another study (`force`); notify(event, case id,
    message) hears of every case (see `run_jobs`)."""

    workers: int | None = None
    scheduler: str | None = None
    scheduler_file: str | Path | None = None  # the JSON file a Dask scheduler wrote, instead of its address
    retry_failed: bool = False
    rerun_all: bool = False
    force: bool = False
    notify: Callable[[str, str, str], None] | None = None
    threads: int | None = None  # each case's threads, instead of its scene's or its share of the processors


@dataclass
class SweepReport:
    """What a sweep did; `study` is the combined dataset's path."""

    study: Path
    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    removed: list[Path] = field(default_factory=list)
    damaged: list[str] = field(default_factory=list)  # finished cases whose files did not read back: run again
    outdated: dict[str, str] = field(default_factory=dict)  # reused cases made by other software versions
    alerts: dict[str, dict[str, str]] = field(default_factory=dict)  # `quantities.alerts`: attribute -> case -> said
    series: dict[str, dict] = field(default_factory=dict)  # case run -> "time" and its job's `measure` (its worker's)

    @property
    def ok(self) -> bool:
        return not self.failed

    def warnings(self) -> list[str]:
        """What a user should know besides the counts: damaged files computed again, outdated cases kept, and
        what `quantities.alerts` said of the cases."""
        said = []
        if self.damaged:
            said.append(f"{len(self.damaged)} case file{'s were' if len(self.damaged) > 1 else ' was'} damaged "
                        f"(could not be read whole: header, attributes or data) and computed again: "
                        f"{', '.join(self.damaged[:10])}{', ...' if len(self.damaged) > 10 else ''}")
        if self.outdated:
            versions = sorted(set(self.outdated.values()))
            said.append(f"{len(self.outdated)} finished cases were computed by other software versions "
                        f"({'; '.join(versions[:2])}{'; ...' if len(versions) > 2 else ''}) and were reused; "
                        "--rerun-all computes every case again")
        said += alerts.summaries(self.alerts, "cases")
        return said

    def note(self, case_id: str, attrs: dict) -> None:
        """Keep what `quantities.alerts` recorded of a case (in its file's attributes or as it was written)."""
        for name in alerts.ATTRIBUTES:
            if attrs.get(name):
                self.alerts.setdefault(name, {})[case_id] = str(attrs[name])


@dataclass(frozen=True)
class Job:
    """One simulation to run and record under DIR/cases/<id>.nc: a validated scene and where it came from."""

    id: str
    scene: Scene
    scene_file: Path
    overrides: str  # the overrides as TOML text, for the record
    attrs: dict = field(default_factory=dict)  # stamped onto the case file (case id, study file, ...)
    layout: case_files.CaseLayout | None = None  # a study's case: its place in the study, in its file
    measure: tuple[str, ...] = ()  # observables whose series its worker hands back (`SweepReport.series`)


NUMERIC_PACKAGES = ("numpy", "scipy", "fipy", "pyamg", "scikit-fem")  # what a result's numbers depend on


def software_versions() -> dict[str, str]:
    """The versions a case file records (`biostudy_version`, `version_<package>`) that its numbers depend on."""
    return {"biostudy_version": provenance.version(), **versions(NUMERIC_PACKAGES, python=False)}


def _outdated(record: dict) -> str:
    """'' if a case file was made by the software running now, else which versions differ, e.g.
    'biostudy 0.0.1 (now 0.1.0), scipy 1.11.4 (now 1.12.0)'."""
    now = software_versions()
    return ", ".join(f"{k.removeprefix('version_').removesuffix('_version').replace('_', '-')} {record[k]} "
                     f"(now {v})" for k, v in now.items() if k in record and str(record[k]) != v)


def run_jobs(jobs: list[Job], out_dir: str | Path, execution: Execution = Execution(),
             *, tidy: bool = True, backend: Backend | None = None) -> SweepReport:
    """Run every job not yet recorded under DIR/cases/ and record each one (dataset or failure).

    A case file whose fingerprint matches the job's compiled problem is finished work: it is skipped (a
    recorded failure too, unless `execution.retry_failed`) once its data read back with their checksums (a
    damaged file is run again); `execution.rerun_all` runs every job again.  notify(event, id, message) is
    called with event "skip", "start" (once per job to run, before any runs), "done", "failed" or "note" (no
    id: a message while waiting, e.g. for workers).  Without workers or a scheduler jobs run here, one after
    another; `backend` (a `backends.Kept`) runs them on the caller's workers instead of new ones (a
    calibration's rounds).  The caller holds the directory (`targets.owned`); `tidy`: it holds it alone, and
    removes the temporaries dead writers left (an array task does not: a writer on another node is alive though
    no process here has its id).  A case file that exists but that biostudy did not write is `BadInput` before
    anything runs; a lost Dask scheduler is a `SweepError` that says what was kept.
    """
    scheduler = execution.scheduler or execution.scheduler_file
    if execution.workers and not scheduler:
        pool.warm_up()  # the workers' imports overlap the checks below
    out_dir = Path(out_dir)
    report = _started(out_dir, tidy)
    notify = execution.notify or (lambda *args: None)
    by_id = {job.id: job for job in jobs}
    prints, events = _sorted_out(jobs, out_dir, execution, report)
    ids = [job_id for event, job_id, _ in events if event == "start"]
    _check_room({i: by_id[i].scene for i in ids}, 0 if scheduler else (execution.workers or 1), out_dir)
    for event in events:
        notify(*event)
    if backend is None or not ids:
        backend = _backend(execution, bool(ids), lambda message: notify("note", "", message))
    made_by = netcdf.made_by()

    def task(job_id: str) -> Task:
        job = by_id[job_id]
        path = case_files.case_file(out_dir, job_id).absolute()  # workers started before a chdir keep theirs
        return Task(_threaded(job.scene.problem(), execution.threads), _record(job, prints[job_id]),
                    str(path) if backend.sees_files else None, job.layout, job.measure, made_by)

    try:
        with contextlib.closing(windowed(ids, task, backend)) as results:
            for job_id, outcome in results:
                _recorded(by_id[job_id], out_dir, outcome, prints[job_id], made_by)
                report.note(job_id, outcome.attrs)
                report.ran.append(job_id)
                if outcome.series:
                    report.series[job_id] = outcome.series
                if outcome.status != "done":
                    report.failed[job_id] = outcome.message
                notify(outcome.status, job_id, outcome.message)
    except SchedulerLost as lost:
        raise SweepError(f"{lost}; {_kept(report, len(ids))}") from None
    return report


def _threaded(problem: solver.Problem, threads: int | None) -> solver.Problem:
    """The case's problem, on `threads` threads if given (``--threads``; no part of its identity)."""
    if threads is None:
        return problem
    return dataclasses.replace(problem, numerics=dataclasses.replace(problem.numerics, threads=threads))


def _started(out_dir: Path, tidy: bool) -> SweepReport:
    """The report of a sweep into `out_dir` (DIR/cases made); `tidy`: the temporaries dead writers left removed."""
    cases_dir = out_dir / "cases"
    cases_dir.mkdir(parents=True, exist_ok=True)
    report = SweepReport(out_dir / "study.nc")
    if tidy:
        report.removed = writing.remove_temporaries(cases_dir) + writing.remove_temporaries(out_dir)
    return report


def _sorted_out(jobs: list[Job], out_dir: Path, execution: Execution,
                report: SweepReport) -> tuple[dict[str, str], list[tuple[str, str, str]]]:
    """Each job's fingerprint, and the events that say which are finished ("skip", told in `report`) and which
    run ("start"; a damaged file among them, in `report`).  `BadInput` for every case file biostudy did not
    write, before anything runs."""
    prints, events, foreign = {}, [], []
    for job in jobs:
        problem = job.scene.problem()
        prints[job.id] = fingerprint(problem)
        path = case_files.case_file(out_dir, job.id)
        record = case_files.recorded(path)
        if record is not None and "biostudy_version" not in record:
            foreign.append(BadInput("exists and is not a dataset biostudy wrote; refusing to overwrite it, --force "
                                    "or not (move it away, or give another -o)", path))
            continue
        same = record is not None and matches(record.get("fingerprint"), prints[job.id], legacy_fingerprint(problem))
        reusable = same and not execution.rerun_all \
            and (record.get("status") == "done" or (record.get("status") == "failed" and not execution.retry_failed))
        if path.exists() and (record is None or reusable and not netcdf_io.intact(path)):
            report.damaged.append(job.id)  # a file that cannot be read whole: its header, attributes or data
        elif reusable:
            _skipped(report, job.id, record)
            events.append(("skip", job.id, str(record.get("status"))))
            continue
        events.append(("start", job.id, ""))
    if foreign:
        raise BadInput.every(foreign)
    return prints, events


def _skipped(report: SweepReport, job_id: str, record: dict) -> None:
    """Tell `report` of a finished case reused: a failure recorded, other software versions, its alerts."""
    report.skipped.append(job_id)
    if record.get("status") == "failed":
        report.failed[job_id] = str(record.get("message", ""))
    outdated = _outdated(record)
    if outdated:
        report.outdated[job_id] = outdated
    report.note(job_id, record)


def _check_room(scenes: dict[str, Scene], processes: int, out_dir: Path) -> None:
    """`BadInput` before any case runs if the cases to run (by id) do not fit the memory of `processes` at once (0:
    on a cluster) or the disk: the case files and the summary stacking them; or if BIOSTUDY_THREADS, which the
    cases run here take their threads from, is no thread count (`inputs.cores`)."""
    cores.available()
    estimates = {job_id: resources.estimate(scene) for job_id, scene in scenes.items()}
    too_big = resources.run_problem(estimates, processes, out_dir, 2 * sum(e.disk for e in estimates.values()))
    if too_big:
        raise BadInput(too_big, out_dir)


def _backend(execution: Execution, work: bool, note: Callable[[str], None]) -> Backend:
    """Where the cases run (`backend`; nothing to run: here)."""
    return backend(execution, note) if work else Here()


def backend(execution: Execution, note: Callable[[str], None] | None = None) -> Backend:
    """Where the cases run: on the Dask scheduler (its address, or its scheduler file), on `workers` local
    processes, else here; `note` hears what a wait is for (workers that have not come)."""
    if execution.scheduler or execution.scheduler_file:
        return DaskCluster(execution.scheduler, note or (lambda message: None), execution.scheduler_file)
    return LocalPool(execution.workers) if execution.workers else Here()


def _kept(report: SweepReport, to_run: int) -> str:
    """What an interrupted sweep kept: '3 cases recorded in DIR/cases are kept (2 of 5 to run did not finish);
    run the same command again to resume'."""
    recorded = len(report.ran) + len(report.skipped)
    return (f"{recorded} case{'s' if recorded != 1 else ''} recorded in {report.study.parent / 'cases'} "
            f"{'are' if recorded != 1 else 'is'} kept ({to_run - len(report.ran)} of {to_run} to run did not "
            "finish); run the same command again to resume")


def plan_jobs(plan: Plan, **attrs) -> list[Job]:
    """One job per case of a study or catalogue; each case file records the case's id and its own
    attributes, the overrides that made it and `attrs` (e.g. the study file)."""
    return [Job(case.id, plan.scenes[case.id], plan.scene_file, overrides_text({**plan.common, **case.overrides()}),
                {"case_id": case.id, **attrs, **case.attrs})
            for case in plan.cases]


def plan_owner(plan: Plan, kind: str) -> ownership.Owner:
    """Who a study's or catalogue's directory belongs to: its kind, name, base scene and swept keys."""
    keys = tuple(plan.keys) if kind == "study" else ()
    return ownership.Owner(kind, plan.spec.name, str(plan.scene_file.resolve()), keys)


def _record(job: Job, fingerprint: str) -> Record:
    """What a job's case file records of what produced it (`finish.Record`), with its fingerprint."""
    return Record.of(job.scene, job.scene_file, job.overrides, **job.attrs, fingerprint=fingerprint)


def _recorded(job: Job, out_dir: Path, outcome: Outcome, fingerprint: str, made_by: str) -> None:
    """What this process does for a case its worker finished: nothing but put its file's bytes in place (a Dask
    worker's), or write the failure's record of a worker that died without writing one (its temporary removed);
    a case file that could not be written stops the sweep (`SweepError`): the cases recorded so far are kept."""
    path = case_files.case_file(out_dir, job.id)
    try:
        if outcome.unwritten:
            raise writing.NotWritten(outcome.errno, outcome.unwritten)
        if outcome.data is not None:
            writing.atomic(path, lambda temporary: temporary.write_bytes(outcome.data), fsync=True)
        elif not outcome.written:
            writing.remove_temporaries(path.parent, of=path.name)  # a dead worker's half-written file
            died = Simulated("failed", None, outcome.message, outcome.seconds, outcome.error)
            with netcdf.called(made_by):
                ds = failure_record(_record(job, fingerprint), job.scene.name, died)
            writing.write_atomic(job.layout.apply(ds) if job.layout else ds, path)
    except OSError as error:  # `writing.NotWritten`: a full disk says which
        resume = "run the same command again to resume" + (" once there is room" if error.errno == errno.ENOSPC
                                                           else "")
        raise SweepError(f"{error}; the cases recorded before are kept, {resume}") from None
