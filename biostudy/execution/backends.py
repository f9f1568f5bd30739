"""Where cases run, and the one loop that hands them out: here, on local processes, or on a Dask cluster.

A backend takes a case (its id and compiled `solver.Problem`) with `submit`,
tells with `finished` which cases are over (waiting for at least one), and
ends what is still running with `close`.  `windowed` is the submit loop every
backend shares: at most `capacity` cases in flight, each compiled just before
it is handed out, so a sweep of a thousand large cases never holds a thousand
problems in memory; a backend that finishes a case gets its next one before
this process records the finished one (writing a file takes no worker's time).
"""
from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Callable, Iterator, Protocol

from . import interrupts
from .worker import Outcome, solve

if TYPE_CHECKING:
    import solver

Compile = Callable[[str], "solver.Problem"]


class Backend(Protocol):
    capacity: int  # cases in flight at most

    @property
    def busy(self) -> int:
        """Cases in flight."""

    def submit(self, case_id: str, problem: "solver.Problem") -> None: ...

    def finished(self) -> list[tuple[str, Outcome]]:
        """(case id, Outcome) of the cases that are over; waits until there is at least one."""

    def close(self, completed: bool) -> None:
        """End what still runs (`completed`: nothing does)."""


class Here:
    """Cases in this process, one after another."""

    capacity = 1

    def __init__(self):
        self.waiting: list[tuple[str, "solver.Problem"]] = []

    @property
    def busy(self) -> int:
        return len(self.waiting)

    def submit(self, case_id: str, problem: "solver.Problem") -> None:
        self.waiting.append((case_id, problem))

    def finished(self) -> list[tuple[str, Outcome]]:
        case_id, problem = self.waiting.pop()
        with interrupts.allowed():  # the simulation: an interruption ends it at once
            outcome = solve(problem)
        return [(case_id, outcome)]

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
        self.ended = False

    @property
    def busy(self) -> int:
        return self.backend.busy

    def submit(self, case_id: str, problem: "solver.Problem") -> None:
        self.backend.submit(case_id, problem)

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
