"""What runs in a worker process: one simulation, its failure turned into a record.

Kept apart from the rest of biostudy (no pydantic, no files) so a worker
process starts by importing only the solver.  `solve` never raises for a
failed simulation: a sweep records the failure and goes on.
"""
from __future__ import annotations

import dataclasses
import os
import platform
import signal
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import first_line
from ..inputs import cores

if TYPE_CHECKING:
    import xarray as xr

    import solver


# FiPy picks its solver suite once, when it is first imported; the solver reads FiPy's matrices as scipy
# ones, so every process that simulates pins the scipy suite before that (whatever else is installed).
SOLVER_ENV = {"FIPY_SOLVERS": "scipy"}


def pin_solvers() -> None:
    """At the start of a process that simulates (the command line, a worker): FiPy's scipy suite."""
    for name, value in SOLVER_ENV.items():
        os.environ.setdefault(name, value)


@dataclass
class Outcome:
    """What a worker sends back for one case."""

    status: str  # "done" or "failed"
    dataset: "xr.Dataset | None"
    message: str
    seconds: float
    error: str = ""  # class of the exception that ended a failed run, e.g. "MechanicsError"


def start() -> None:
    """The start of a local worker process (`serve`): the parent handles Ctrl-C and SIGTERM and ends the workers,
    so a worker must not die mid-task on its own (a batch system's SIGTERM reaches every process of the job, the
    workers maybe first: their cases would be recorded as failed); the solver is imported while the parent
    prepares."""
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.SIG_IGN)
    import solver.output  # noqa: F401  (FiPy, xarray: a second of imports before the first case arrives)


def serve(tasks, lifeline) -> None:
    """A local worker process (`pool.LocalPool`): solve each problem that comes through `tasks` and send back
    its `Outcome`, until `tasks` closes.

    `lifeline` is the reading end of a pipe whose only writer is the sweep's process: when that process
    ends, however it ends (SIGKILL included), the pipe closes and this process ends at once, even in the
    middle of a simulation, instead of computing on for nobody (and keeping the fork server and the resource
    tracker alive with it).
    """
    start()
    threading.Thread(target=_end_with, args=(lifeline,), name="lifeline", daemon=True).start()
    while True:
        try:
            problem = tasks.recv()
        except (EOFError, OSError):
            return  # the sweep is done with this worker
        outcome = solve(problem)
        try:
            tasks.send(outcome)
        except (BrokenPipeError, OSError):
            return


def _end_with(lifeline) -> None:
    try:
        lifeline.recv_bytes()  # nothing is ever sent: returns (EOFError) when the sweep's process has ended
    except (EOFError, OSError):
        pass
    os._exit(1)


def provenance() -> dict[str, str]:
    """Where and how a run was computed (thread settings change its speed, not its result)."""
    return {"host": platform.node(), "omp_num_threads": os.environ.get("OMP_NUM_THREADS", "unset"),
            "fipy_solvers": os.environ.get("FIPY_SOLVERS", "unset")}


def with_threads(problem: "solver.Problem", sharing: int = 1, threads: int | None = None) -> "solver.Problem":
    """`problem` with the threads it runs on: `threads` if given (``--threads``), else its own (`[numerics]
    threads`), else the processors this process may use (`inputs.cores`) shared among `sharing` cases computed on
    this machine at once, at least one each.  The count changes how fast a case runs, never its result or its
    identity (`identity.fingerprint`)."""
    if threads is None and problem.numerics.threads is not None:
        return problem
    count = threads or max(1, cores.available().count // max(1, sharing))
    return dataclasses.replace(problem, numerics=dataclasses.replace(problem.numerics, threads=count))


def solve(problem: "solver.Problem", sharing: int = 1) -> Outcome:
    """Simulate one problem (on its threads, `with_threads`); a failure becomes an `Outcome`, never an exception."""
    pin_solvers()  # a Dask worker's process was not started by biostudy: before FiPy is first imported
    from solver import SimulationError, simulate  # lazily: after pin_solvers, before FiPy is first imported

    began = time.perf_counter()
    try:
        ds = simulate(with_threads(problem, sharing))
    except SimulationError as error:
        return Outcome("failed", None, str(error), time.perf_counter() - began, type(error).__name__)
    except Exception as error:  # a bug or resource problem in this case must not sink the others
        frame = traceback.extract_tb(error.__traceback__)[-1]
        where = f" (at {Path(frame.filename).name}:{frame.lineno})"
        message = f"{type(error).__name__}: {str(error) and first_line(error)}{where}"
        if isinstance(error, MemoryError):
            message = f"out of memory ({message})"
        return Outcome("failed", None, message, time.perf_counter() - began, type(error).__name__)
    ds.attrs.update(provenance())
    return Outcome("done", ds, "", time.perf_counter() - began)
