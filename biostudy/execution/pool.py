"""Local worker processes of a sweep: one case each at a time, replaced when one dies, ended with the sweep.

Workers are forked from a fork server that imported the solver once (start-up ~0.1 s instead of ~1.2 s of
imports per worker), fresh interpreters (spawn) where there is no fork server; they start with
``OMP_NUM_THREADS=1`` (BLAS's own threads: FiPy's suite ran 40x slower with unrestricted threads) and
``FIPY_SOLVERS=scipy``.  The workers share the machine's processors: a case runs on its scene's threads, else
on the processors here divided by the workers (`worker.with_threads`).  What a worker runs is `worker.serve`; the
loop that hands cases out is `backends.windowed`.

Each worker has a pipe of its own for problems and outcomes, so a worker that dies (SIGKILL, the kernel's
out-of-memory killer, a crash in a library) takes only its own case with it: that case is recorded as
failed ("worker died: signal 9 ..."), a new worker takes its place and the others compute on.  Ctrl-C and
SIGTERM are this process's to handle: a worker ignores both (a batch system's SIGTERM to every process of a
job would otherwise fail the cases in flight) and is ended by this process, with SIGKILL.  Every worker
also holds the reading end of a "lifeline" pipe whose only writer is this process: when this process ends,
however it ends, the workers end too (`worker.serve`), and the fork server and the resource tracker after
them.

The fork server is a process of its own, killed from outside as easily as a worker (`kill -9` of every child
of a sweep): a worker it was starting is started afresh, spawned (the fork server's answer, its pid, is lost:
``EOFError``, which click would have reported as an interruption); a worker it had started computes on (its
end is then seen on its task pipe alone: the fork server's report of it, the sentinel, is gone).

This module imports nothing heavy (no solver, no xarray): `warm_up` can start the fork server before the
command line has imported the rest, so the two import at once.
"""
from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import multiprocessing.connection
import os
import signal
import time
from dataclasses import dataclass

from . import interrupts, worker
from .worker import Outcome, Task

WORKER_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", **worker.SOLVER_ENV}


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


def _context():
    """Workers forked from a fork server that imported the solver once (start-up ~0.1 s instead of ~1.2 s of
    imports per worker); fresh interpreters (spawn) where there is no fork server."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["biostudy.execution.worker", *worker.IMPORTS])
        return context
    return multiprocessing.get_context("spawn")


def warm_up() -> None:
    """Start the fork server now, so that its imports (~1 s) overlap this process's own work (validating,
    fingerprinting, checking finished cases) instead of delaying the first case.  Idempotent."""
    context = _context()
    if context.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        with _environment(WORKER_ENV):
            forkserver.ensure_running()


@dataclass
class _Worker:
    process: multiprocessing.Process
    tasks: multiprocessing.connection.Connection  # tasks out, outcomes back
    case_id: str | None = None  # the case it is solving
    began: float = 0.0
    orphaned: bool = False  # its fork server is gone: its sentinel says nothing, its end shows on `tasks` alone


def _death(exitcode: int | None) -> str:
    """Why a worker process ended without an answer, for the case's record."""
    if exitcode is None:
        return "worker died: it stopped answering and did not end"
    if exitcode == -signal.SIGKILL:  # what the kernel's out-of-memory killer sends, too
        return "worker died: signal 9 (SIGKILL: killed from outside, or out of memory)"
    if exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = "unknown signal"
        return f"worker died: signal {-exitcode} ({name})"
    return f"worker died: exit status {exitcode}"


class LocalPool:
    """Local worker processes, one case each at a time; started as cases need them, replaced when one dies.
    A `backends.Backend`: `submit` hands a case to an idle worker (a new one if none is idle), `finished`
    waits for answers and deaths, `close` ends every worker."""

    sees_files = True  # a worker writes its case's file (`worker.perform`)

    def __init__(self, size: int):
        self.context = _context()
        self.capacity = size
        self.workers: list[_Worker] = []
        # every worker holds the reading end; the writing end exists only in this process (see worker.serve)
        self.lifeline, self._lifeline_writer = self.context.Pipe(duplex=False)

    @property
    def busy(self) -> int:
        return sum(w.case_id is not None for w in self.workers)

    def _start(self) -> _Worker:
        """A new worker; spawned if the fork server died while it started one (module docstring)."""
        try:
            return self._started()
        except (EOFError, OSError):
            if self.context.get_start_method() != "forkserver":
                raise
            self.context = multiprocessing.get_context("spawn")
            return self._started()

    def _started(self) -> _Worker:
        ours, theirs = self.context.Pipe()
        process = self.context.Process(target=worker.serve, args=(theirs, self.lifeline), daemon=True,
                                       name=f"biostudy-worker-{len(self.workers)}")
        try:
            # Ctrl-C and SIGTERM wait for the start: a process the fork server is still starting when its parent
            # goes away dies with a traceback (it cannot read its start-up data)
            with _environment(WORKER_ENV), interrupts.deferred():
                process.start()
        except BaseException:
            ours.close()
            raise
        finally:
            theirs.close()  # only the worker holds its end: a worker that dies closes the pipe
        self.workers.append(_Worker(process, ours))
        return self.workers[-1]

    def submit(self, case_id: str, task: Task) -> None:
        # the processors here, shared by the workers
        task = dataclasses.replace(task, problem=worker.with_threads(task.problem, self.capacity))
        idle = next((w for w in self.workers if w.case_id is None), None) or self._start()
        try:
            idle.tasks.send(task)
        except (BrokenPipeError, OSError):  # it died while idle: a fresh one takes the case
            self._drop(idle)
            idle = self._start()
            idle.tasks.send(task)
        idle.case_id, idle.began = case_id, time.perf_counter()

    def _drop(self, gone: _Worker) -> None:
        self.workers.remove(gone)
        gone.tasks.close()
        gone.process.join(5)

    def finished(self) -> list[tuple[str, Outcome]]:
        """Wait until at least one busy worker has answered or died; (case id, Outcome) of each."""
        while True:
            done = self._over()
            if done:
                return done

    def _over(self) -> list[tuple[str, Outcome]]:
        """(case id, Outcome) of the busy workers that have answered or died once one of them is heard from:
        none if that was only the news that a worker's fork server is gone."""
        busy = [w for w in self.workers if w.case_id is not None]
        with interrupts.allowed():  # waiting: an interruption ends it; reading an answer, it waits (`windowed`)
            ready = set(multiprocessing.connection.wait([w.tasks for w in busy] +
                                                        [w.process.sentinel for w in busy if not w.orphaned]))
        done = []
        for w in busy:
            if w.tasks not in ready and (w.orphaned or w.process.sentinel not in ready):
                continue
            if w.tasks not in ready and not w.tasks.poll():  # its fork server ended, not it: a worker that
                w.orphaned = True                             # ends has closed its task pipe by then
                continue
            case_id, w.case_id = w.case_id, None
            try:
                if w.tasks.poll():
                    done.append((case_id, w.tasks.recv()))
                    continue
            except (EOFError, OSError):
                pass
            self._drop(w)
            death = _death(w.process.exitcode) if not w.orphaned else \
                "worker died (how is unknown: the fork server that started it had been killed)"
            done.append((case_id, Outcome("failed", death, time.perf_counter() - w.began, "WorkerDied")))
        return done

    def close(self, completed: bool) -> None:
        """Done: workers end when their task pipe closes.  Interrupted: running simulations cannot be
        cancelled, only ended (SIGKILL: a worker ignores SIGTERM, `worker.start`; it holds no file)."""
        for w in self.workers:
            if not completed and w.orphaned:  # its Process says it ended (the fork server's report is gone)
                if not w.tasks.poll():
                    os.kill(w.process.pid, signal.SIGKILL)
            elif not completed:
                w.process.kill()
            w.tasks.close()
        for w in self.workers:
            w.process.join(10)
            if w.process.exitcode is None:
                w.process.kill()
                w.process.join(5)
        self._lifeline_writer.close()
        self.lifeline.close()
