"""Running scenes: one case here, a sweep serially, on N local processes or on a Dask cluster.

Workers only simulate: they receive a compiled `solver.Problem` (plain
arrays, no files) and send back the dataset or the reason it failed.  This
process alone writes files, each atomically (`store.write_atomic`), so a
cluster needs no shared filesystem and an interruption (Ctrl-C, SIGTERM, a
kill) never leaves a half-written file under a final name.

A case that fails (the solver's `SimulationError`, or any other exception
inside the simulation) is recorded as failed and the others go on.  Local
worker processes start with ``OMP_NUM_THREADS=1`` (one simulation per core;
FiPy's suite ran 40x slower with unrestricted threads) and
``FIPY_SOLVERS=scipy``; Dask's nanny sets the thread variables for its
workers itself.  What runs in a worker is in `biostudy.worker`.
"""
from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import os
import signal
import threading
import uuid
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator

import numpy as np

from . import combine, store, worker
from .errors import BadInput
from .scene import Scene, overrides_text
from .study import Plan
from .worker import Outcome, solve

if TYPE_CHECKING:
    import solver

CONNECT_TIMEOUT = "10s"  # to reach a Dask scheduler
WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", **worker.SOLVER_ENV}


class SweepError(RuntimeError):
    """The sweep cannot go on (its workers are gone); cases finished so far are kept."""


# ---------------------------------------------------------------------------------------------
# Where cases run: each backend takes the case ids to run and a function compiling one case's
# problem, and yields (case id, Outcome) as cases finish.  Problems are compiled just before they
# are handed out and at most a few per worker are in flight, so a sweep of a thousand large cases
# does not hold a thousand problems in memory.

Compile = Callable[[str], "solver.Problem"]


def _serial(ids: list[str], compile_: Compile) -> Iterator[tuple[str, Outcome]]:
    for case_id in ids:
        yield case_id, solve(compile_(case_id))


@contextlib.contextmanager
def _environment(values: dict[str, str]):
    """Set environment variables for processes started inside the block (the parent's own libraries
    are already loaded, so this changes nothing for this process)."""
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def _interruptions_deferred():
    """Ctrl-C and SIGTERM wait until the block is done, then act as they would have.

    Around the start of a worker process: a process the fork server is still starting when its parent
    goes away dies with a traceback (it cannot read its start-up data), and one that started but is not
    yet registered with the pool would never be ended.  Signal handlers exist in the main thread only.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = {number: signal.signal(number, lambda signum, frame: received.append(signum))
                for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        if received:
            signal.raise_signal(received[0])


def _context():
    """Workers forked from a fork server that imported the solver once (start-up ~0.1 s instead of ~1.2 s of
    imports per worker); fresh interpreters (spawn) where there is no fork server."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["biostudy.worker", "solver.output", "fipy"])
        return context
    return multiprocessing.get_context("spawn")


def _windowed(ids: list[str], compile_: Compile, window: int, submit: Callable, first_done: Callable,
              result: Callable, running: dict) -> Iterator[tuple[str, Outcome]]:
    """The submit loop every pool shares: at most `window` cases in flight, each compiled just before it
    is handed out; yields (case id, Outcome) as cases finish.

    submit(problem, case id) -> future; first_done(futures) -> the finished ones (at least one);
    result(future) -> its Outcome.  `running` (future -> case id) is the caller's, so that it can end
    what is still in flight when the loop is left early.
    """
    waiting = list(reversed(ids))

    def fill():
        while waiting and len(running) < window:
            case_id = waiting.pop()
            running[submit(compile_(case_id), case_id)] = case_id

    fill()
    while running:
        for future in first_done(list(running)):
            case_id = running.pop(future)
            yield case_id, result(future)
        fill()


def _local(ids: list[str], compile_: Compile, workers: int) -> Iterator[tuple[str, Outcome]]:
    executor = ProcessPoolExecutor(max_workers=workers, mp_context=_context(), initializer=worker.start)
    running: dict = {}
    finished = False

    def submit(problem, case_id):
        with _environment(WORKER_ENV), _interruptions_deferred():  # worker processes start on submit
            return executor.submit(solve, problem)

    def result(future) -> Outcome:
        try:
            return future.result()
        except BrokenProcessPool:
            raise SweepError("a worker process died (out of memory?); finished cases are kept, run "
                             "the sweep again to resume") from None

    try:
        yield from _windowed(ids, compile_, 2 * workers, submit,
                             lambda futures: wait(futures, return_when=FIRST_COMPLETED).done, result, running)
        finished = True
    finally:
        if finished:
            executor.shutdown(wait=True)
        else:  # interrupted or failed: running simulations cannot be cancelled, only ended
            processes = list((getattr(executor, "_processes", None) or {}).values())
            executor.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                process.terminate()


def _dask(ids: list[str], compile_: Compile, address: str) -> Iterator[tuple[str, Outcome]]:
    from distributed import Client
    from distributed import wait as dask_wait

    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as error:
        raise BadInput(f"cannot connect to a Dask scheduler at {address} ({error})", "--scheduler") from None
    run = uuid.uuid4().hex[:8]
    running: dict = {}

    def submit(problem, case_id):
        return client.submit(solve, problem, key=f"biostudy-{case_id}-{run}", pure=False)

    def result(future) -> Outcome:
        try:
            return future.result()
        except Exception as error:  # e.g. KilledWorker: the case took its worker down
            return Outcome("failed", None, f"{type(error).__name__}: {error}", float("nan"))

    try:
        yield from _windowed(ids, compile_, max(4, 2 * sum(client.nthreads().values())), submit,
                             lambda futures: dask_wait(futures, return_when="FIRST_COMPLETED").done, result,
                             running)
    finally:
        if running:
            client.cancel(list(running))
        client.close()


# ---------------------------------------------------------------------------------------------


@dataclass
class SweepReport:
    """What a sweep did; `study` is the combined dataset's path."""

    study: Path
    ran: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    removed: list[Path] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failed


@dataclass(frozen=True)
class Job:
    """One simulation to run and record under DIR/cases/<id>.nc: a validated scene and where it came from."""

    id: str
    scene: Scene
    scene_file: Path
    overrides: str  # the overrides as TOML text, for the record
    attrs: dict = field(default_factory=dict)  # stamped onto the case file (case id, study file, ...)
    layout: combine.CaseLayout | None = None  # a study's case: its place in the study, in its file


def fingerprint(problem: "solver.Problem") -> str:
    """sha256 of everything that determines a run's result (not its name)."""
    digest = hashlib.sha256()
    for part in (problem.grid, problem.params, problem.numerics, problem.mechanics, problem.consumption,
                 problem.t_end, problem.steps):
        digest.update(repr(part).encode())
    for array in (problem.phi0, problem.nutrient_fixed, problem.nutrient_value, problem.obstacle,
                  problem.output_times):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def run_jobs(jobs: list[Job], out_dir: str | Path, workers: int | None = None, scheduler: str | None = None,
             retry_failed: bool = False, notify: Callable[[str, str, str], None] | None = None) -> SweepReport:
    """Run every job not yet recorded under DIR/cases/ and record each one (dataset or failure).

    A case file whose fingerprint matches the job's compiled problem is finished work: it is skipped
    (a recorded failure too, unless `retry_failed`).  notify(event, id, message) is called with event
    "skip", "start" (once per job to run, before any runs), "done" or "failed".  Without `workers` or
    `scheduler` jobs run here, one after another.
    """
    out_dir = Path(out_dir)
    cases_dir = out_dir / "cases"
    cases_dir.mkdir(parents=True, exist_ok=True)
    report = SweepReport(out_dir / "study.nc")
    report.removed = store.remove_temporaries(cases_dir) + store.remove_temporaries(out_dir)
    notify = notify or (lambda *args: None)
    by_id = {job.id: job for job in jobs}

    ids, prints = [], {}
    for job in jobs:
        prints[job.id] = fingerprint(job.scene.problem())
        record = store.recorded(store.case_file(out_dir, job.id))
        if record and record.get("fingerprint") == prints[job.id] and (
                record.get("status") == "done" or (record.get("status") == "failed" and not retry_failed)):
            report.skipped.append(job.id)
            if record.get("status") == "failed":
                report.failed[job.id] = str(record.get("message", ""))
            notify("skip", job.id, str(record.get("status")))
            continue
        ids.append(job.id)
        notify("start", job.id, "")

    def compile_(job_id: str) -> "solver.Problem":
        return by_id[job_id].scene.problem()

    if not ids:
        results = _serial([], compile_)
    elif scheduler:
        results = _dask(ids, compile_, scheduler)
    elif workers:
        results = _local(ids, compile_, workers)
    else:
        results = _serial(ids, compile_)
    with contextlib.closing(results):
        for job_id, outcome in results:
            _record(by_id[job_id], out_dir, outcome, prints[job_id])
            report.ran.append(job_id)
            if outcome.status != "done":
                report.failed[job_id] = outcome.message
            notify(outcome.status, job_id, outcome.message)
    return report


def plan_jobs(plan: Plan, **attrs) -> list[Job]:
    """One job per case of a study or catalogue; each case file records the case's id and its own
    attributes, the overrides that made it and `attrs` (e.g. the study file)."""
    return [Job(case.id, plan.scenes[case.id], plan.scene_file, overrides_text({**plan.fixed, **case.overrides()}),
                {"case_id": case.id, **attrs, **case.attrs})
            for case in plan.cases]


def sweep(plan: Plan, out_dir: str | Path, workers: int | None = None, scheduler: str | None = None,
          retry_failed: bool = False, notify: Callable[[str, str, str], None] | None = None) -> SweepReport:
    """Run every case not yet recorded, write DIR/cases/<id>.nc for each and DIR/study.nc (see `run_jobs`)."""
    layouts = combine.case_layouts(plan)
    jobs = [replace(job, layout=layouts[job.id]) for job in plan_jobs(plan, study_file=str(plan.file.resolve()))]
    report = run_jobs(jobs, out_dir, workers, scheduler, retry_failed, notify)
    combine.write_study(plan, Path(out_dir))
    return report


def _record(job: Job, out_dir: Path, outcome: Outcome, fingerprint: str) -> None:
    """Write one case's file: its dataset, or the failure record."""
    extra = {**job.attrs, "fingerprint": fingerprint}
    if outcome.status == "done":
        ds = store.stamp(outcome.dataset, job.scene.to_toml(), job.scene_file, job.overrides, status="done",
                         message="", **extra)
    else:
        ds = store.failure_record(outcome.message, outcome.seconds, job.scene.name, job.scene.to_toml(),
                                  job.scene_file, job.overrides, error=outcome.error, **extra)
    store.write_atomic(job.layout.apply(ds) if job.layout else ds, store.case_file(out_dir, job.id))
