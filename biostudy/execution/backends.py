"""Where cases run, and the one loop that hands them out: here, on local processes, or on a Dask cluster.

A backend takes a case (its id and `worker.Task`: the compiled problem and
where its file goes) with `submit`, tells with `finished` which cases are over
(waiting for at least one) and what their workers said (`worker.Outcome`), and
ends what is still running with `close`.  `windowed` is the submit loop every
backend shares: at most `capacity` cases in flight, each compiled just before
it is handed out, so a sweep of a thousand large cases never holds a thousand
problems in memory; a backend that finishes a case gets its next one before
this process records the finished one.  `sees_files`: its workers write the case
files into the sweep's directory themselves (local processes, this process);
a Dask cluster's workers may not see it, and hand the files' bytes back.
"""
from __future__ import annotations

from collections import deque
from typing import Callable, Iterator, Protocol

from . import interrupts
from .worker import Outcome, Task, perform

Compile = Callable[[str], Task]


class Backend(Protocol):
    capacity: int  # cases in flight at most
    sees_files: bool  # its workers write into the sweep's directory (else they hand back the files' bytes)

    @property
    def busy(self) -> int:
        """Cases in flight."""

    def submit(self, case_id: str, task: Task) -> None: ...

    def finished(self) -> list[tuple[str, Outcome]]:
        """(case id, Outcome) of the cases that are over; waits until there is at least one."""

    def close(self, completed: bool) -> None:
        """End what still runs (`completed`: nothing does)."""


class Here:
    """Cases in this process, one after another (a serial sweep, an array task)."""

    capacity = 1
    sees_files = True

    def __init__(self):
        self.waiting: list[tuple[str, Task]] = []

    @property
    def busy(self) -> int:
        return len(self.waiting)

    def submit(self, case_id: str, task: Task) -> None:
        self.waiting.append((case_id, task))

    def finished(self) -> list[tuple[str, Outcome]]:
        case_id, task = self.waiting.pop()
        return [(case_id, perform(task))]

    def close(self, completed: bool) -> None:
        self.waiting.clear()


def windowed(ids: list[str], compile_: Compile, backend: Backend) -> Iterator[tuple[str, Outcome]]:
    """Every case of `ids` through `backend`; yields (case id, Outcome) as cases finish.  Leaving the loop
    early (an interruption, an error while recording) closes the backend, which ends what is in flight.
    Ctrl-C and SIGTERM act at once where the backend waits for its cases (`interrupts.allowed`); elsewhere,
    compiling the next case or recording a finished one (the caller, between two items), they wait for it: a
    simulation that finished is never lost to them (`interrupts.deferred`)."""
    waiting = deque(ids)
    completed = False

    def fill():
        while waiting and backend.busy < backend.capacity:
            case_id = waiting.popleft()
            backend.submit(case_id, compile_(case_id))

    try:
        with interrupts.deferred():
            fill()
            while backend.busy:
                done = backend.finished()
                fill()
                yield from done
        completed = True
    finally:
        backend.close(completed)


class Kept:
    """A backend kept open over several `windowed` loops (the rounds of a calibration), so that its workers start
    once: a loop that completes leaves them for the next, one that is interrupted ends them; `end` closes it."""

    def __init__(self, backend: Backend):
        self.backend = backend
        self.capacity = backend.capacity
        self.sees_files = backend.sees_files
        self.ended = False

    @property
    def busy(self) -> int:
        return self.backend.busy

    def submit(self, case_id: str, task: Task) -> None:
        self.backend.submit(case_id, task)

    def finished(self) -> list[tuple[str, Outcome]]:
        return self.backend.finished()

    def close(self, completed: bool) -> None:
        if not completed and not self.ended:
            self.ended = True
            self.backend.close(False)

    def end(self) -> None:
        if not self.ended:
            self.ended = True
            self.backend.close(True)
