"""What runs in a worker: all of one case's work, handed back as a small record.

A worker (a local process, a Dask worker, or the sweep's own process when it runs
cases one after another or as an array task) receives a `Task` (the compiled
problem, what its file records of what produced it, its place in the study and
where its file goes) and does the case's whole work in `perform`: the
simulation (`solve`, which never raises for a failed simulation: a sweep
records the failure and goes on), the dataset finished (`data.finish`: stamp,
observables, alerts), laid out as its study has it, and its case file written
atomically (`writing.write_atomic`, with the sweep's process holding the
directory: `ownership`).  It hands back an `Outcome`: status, message,
seconds, what the alerts said and the series of the observables a caller asked
for (a calibration's residuals), never the fields.  A worker on a Dask cluster,
which may not see the sweep's directory, hands back the file's bytes instead,
which the sweep's process puts in place without reading them.  Imports of
xarray and netCDF are made where a case is finished (a fork server has made
them once, `pool`).
"""
from __future__ import annotations

import dataclasses
import os
import platform
import signal
import threading
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import first_line
from ..inputs import cores
from . import interrupts

if TYPE_CHECKING:
    import numpy as np
    import xarray as xr

    import solver

    from ..data.case_files import CaseLayout
    from ..data.finish import Record


# FiPy picks its solver suite once, when it is first imported; the solver reads FiPy's matrices as scipy
# ones, so every process that simulates pins the scipy suite before that (whatever else is installed).
SOLVER_ENV = {"FIPY_SOLVERS": "scipy"}
# What a worker imports for a case's whole work (the solver, finishing, writing): made once by a fork server (`pool`).
IMPORTS = ("solver.output", "biostudy.data.finish", "biostudy.data.case_files", "biostudy.data.writing",
           "biostudy.data.netcdf_io", "biostudy.quantities.observables", "netCDF4")


def pin_solvers() -> None:
    """At the start of a process that simulates (the command line, a worker): FiPy's scipy suite."""
    for name, value in SOLVER_ENV.items():
        os.environ.setdefault(name, value)


@dataclass
class Simulated:
    """One simulation's result in the worker: its dataset, or why it failed."""

    status: str  # "done" or "failed"
    dataset: "xr.Dataset | None"
    message: str
    seconds: float
    error: str = ""  # class of the exception that ended a failed run, e.g. "MechanicsError"


@dataclass(frozen=True)
class Task:
    """One case as a worker receives it: the compiled problem (its arrays are the bulk of what is sent), what its
    file records of what produced it, its place in its study, and its case file (None: the file's bytes come
    back, for a worker that may not see the sweep's directory)."""

    problem: "solver.Problem"
    record: "Record"
    path: str | None
    layout: "CaseLayout | None" = None
    measure: tuple[str, ...] = ()  # observables whose series come back (a calibration's residuals)
    made_by: str = ""  # the command or call of the sweep, for the file's `history` (`netcdf.made_by`)


@dataclass
class Outcome:
    """What a worker hands back for one case: small, never the fields."""

    status: str  # "done" or "failed"
    message: str
    seconds: float  # the simulation's wall time (until it failed)
    error: str = ""  # class of the exception that ended a failed run, e.g. "MechanicsError", "WorkerDied"
    attrs: dict[str, str] = field(default_factory=dict)  # what `quantities.alerts` said of it
    series: "dict[str, np.ndarray]" = field(default_factory=dict)  # "time" and each of `Task.measure`
    written: bool = False  # its case file is written at `Task.path`
    data: bytes | None = None  # its case file's bytes (`Task.path` None)
    unwritten: str = ""  # why its case file could not be written (`writing.NotWritten`: a full disk, ...)
    errno: int = 0  # of that failure


def start() -> None:
    """The start of a local worker process (`serve`): the parent handles Ctrl-C and SIGTERM and ends the workers,
    so a worker must not die mid-task on its own (a batch system's SIGTERM reaches every process of the job, the
    workers maybe first: their cases would be recorded as failed); the solver is imported while the parent
    prepares."""
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.SIG_IGN)
    import solver.output  # noqa: F401  (FiPy, xarray: a second of imports before the first case arrives)


def serve(tasks, lifeline) -> None:
    """A local worker process (`pool.LocalPool`): perform each `Task` that comes through `tasks` and send back
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
            task = tasks.recv()
        except (EOFError, OSError):
            return  # the sweep is done with this worker
        outcome = perform(task)
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


def _failure(error: BaseException, began: float) -> Simulated:
    """An exception inside a case's work as its failure: the class, the first line and where it was raised."""
    frame = traceback.extract_tb(error.__traceback__)[-1]
    where = f" (at {Path(frame.filename).name}:{frame.lineno})"
    message = f"{type(error).__name__}: {str(error) and first_line(error)}{where}"
    if isinstance(error, MemoryError):
        message = f"out of memory ({message})"
    return Simulated("failed", None, message, time.perf_counter() - began, type(error).__name__)


def with_threads(problem: "solver.Problem", sharing: int = 1, threads: int | None = None) -> "solver.Problem":
    """`problem` with the threads it runs on: `threads` if given (``--threads``), else its own (`[numerics]
    threads`), else the processors this process may use (`inputs.cores`) shared among `sharing` cases computed on
    this machine at once, at least one each.  The count changes how fast a case runs, never its result or its
    identity (`identity.fingerprint`)."""
    if threads is None and problem.numerics.threads is not None:
        return problem
    count = threads or max(1, cores.available().count // max(1, sharing))
    return dataclasses.replace(problem, numerics=dataclasses.replace(problem.numerics, threads=count))


def solve(problem: "solver.Problem", sharing: int = 1) -> Simulated:
    """Simulate one problem (on its threads, `with_threads`); a failure becomes a `Simulated` that says why, never
    an exception."""
    pin_solvers()  # a Dask worker's process was not started by biostudy: before FiPy is first imported
    from solver import SimulationError, simulate  # lazily: after pin_solvers, before FiPy is first imported

    began = time.perf_counter()
    try:
        ds = simulate(with_threads(problem, sharing))
    except SimulationError as error:
        return Simulated("failed", None, str(error), time.perf_counter() - began, type(error).__name__)
    except Exception as error:  # a bug or resource problem in this case must not sink the others
        return _failure(error, began)
    ds.attrs.update(provenance())
    return Simulated("done", ds, "", time.perf_counter() - began)


def finished(task: Task, simulated: Simulated) -> tuple[Simulated, "xr.Dataset"]:
    """The run's dataset finished (`data.finish`: stamp, observables, alerts), or the failure's record; finishing
    that fails (a bug in a measure) fails the case, saying where."""
    from ..data import netcdf
    from ..data.finish import finish

    with netcdf.called(task.made_by or netcdf.made_by()):
        if simulated.status == "done":
            began = time.perf_counter()
            try:
                return simulated, finish(simulated.dataset, task.record, status="done", message="")
            except Exception as error:
                simulated = _failure(error, began - simulated.seconds)
        return simulated, failure_record(task.record, task.problem.name, simulated)


def failure_record(record: "Record", name: str, simulated: Simulated) -> "xr.Dataset":
    """A failed case's record (`case_files.failure_record`) of the scene `name`, stamped with `record`."""
    from ..data import case_files

    return case_files.failure_record(simulated.message, simulated.seconds, name, record.scene, record.scene_file,
                                     record.overrides, error=simulated.error, **record.attrs)


def perform(task: Task) -> Outcome:
    """All of one case's work: `solve`, `finished`, laid out as in its study, its file written (or its bytes
    made); what it says, as its `Outcome`."""
    from ..data import writing
    from ..quantities import alerts, observables

    with interrupts.allowed():  # the simulation (run here): an interruption ends it at once; once it has finished,
        simulated = solve(task.problem)  # one waits until its file is written (`backends.windowed`)
    simulated, ds = finished(task, simulated)
    outcome = Outcome(simulated.status, simulated.message, simulated.seconds, simulated.error,
                      {name: str(ds.attrs[name]) for name in alerts.ATTRIBUTES if ds.attrs.get(name)})
    if simulated.status == "done" and task.measure:
        outcome.series = {"time": ds["time"].values}
        outcome.series.update({name: (ds[name] if name in ds else observables.evaluate(ds, name)).values
                               for name in task.measure})
    if task.layout is not None:
        ds = task.layout.apply(ds)
    if task.path is None:
        outcome.data = _file_bytes(ds)
        return outcome
    try:
        writing.write_atomic(ds, task.path)
    except OSError as error:  # `writing.NotWritten`: the sweep stops, saying why (a full disk: which one)
        outcome.unwritten, outcome.errno = str(error), error.errno or 0
        return outcome
    outcome.written = True
    return outcome


def _file_bytes(ds: "xr.Dataset") -> bytes:
    """The netCDF file of `ds` as `writing.write_atomic` writes it, as bytes (made in a private temporary
    directory of this machine)."""
    import tempfile

    from ..data import netcdf, netcdf_io

    with tempfile.TemporaryDirectory(prefix="biostudy-case-") as directory:
        path = Path(directory) / "case.nc"
        netcdf_io.write(ds, path, netcdf.encoding(ds))
        return path.read_bytes()
