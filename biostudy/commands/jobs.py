"""The start of every job command (sweep, convergence, stability, calibrate), the command line's and Python's.

Where the cases run is checked first (local workers or a Dask cluster, not both; a tls:// cluster's
configuration), the local workers' imports begin while this process loads (`pool.warm_up`), and the command's
`load` reads and validates everything with the options it takes by their declared names (`declared`): bad
input before anything runs.  The caller runs what it gets (`JobCommand.run`) with `Execution(**where)` and its
own way of telling progress.
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ..execution import worker
from .declared import EXECUTION

if TYPE_CHECKING:
    from .finished import JobCommand
    from .options import Command


def started(command: Command, values: dict[str, Any]) -> tuple[JobCommand, dict[str, Any]]:
    """The job of `command` (`biostudy.commands.<name>.load`) loaded from its options' `values`, and where it runs
    (`Execution`'s keywords among them).  The local workers' fork server is started first, before this process
    imports the job machinery (a second): its imports and this process's run at once."""
    from ..execution.dask import check_choice, runs_here  # lazily: -h pays for no execution machinery

    values = dict(values)
    where = {name: values.pop(name) for name in EXECUTION if name in values}
    workers, scheduler, scheduler_file = (where.get(name) for name in ("workers", "scheduler", "scheduler_file"))
    worker.pin_solvers()
    check_choice(workers, scheduler, scheduler_file)
    if workers and not (scheduler or scheduler_file):
        from ..execution.pool import warm_up  # lazily

        warm_up()  # the fork server imports the solver while this process imports it and validates
    load = importlib.import_module(f"{__package__}.{command.name}").load
    return load(**values, runs_here=runs_here(scheduler, scheduler_file)), where
