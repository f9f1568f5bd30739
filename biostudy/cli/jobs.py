"""The one path of every job command of the command line (sweep, convergence, stability, calibrate)."""
from __future__ import annotations

from typing import Callable

import typer

from . import output, progress
from .guard import fail, guarded


def job_command(quiet: bool, load: Callable, as_json: bool = False, **execution) -> None:
    """The one path of every job command (sweep, convergence, stability).

    load() reads and validates (bad input: exit 2 before anything runs) and returns a `commands.JobCommand`,
    which runs the jobs on the chosen pool and says what came of them (`commands.finished.Finished`).  A job
    that failed, or a pool that broke down, is exit status 1.  `as_json`: the result as JSON on stdout
    instead of the table (`output.finished`).
    """
    with guarded():
        from ..execution.dask import check_choice  # lazily: --version and -h pay for no execution machinery
        from ..execution.jobs import Execution  # lazily

        check_choice(execution.get("workers"), execution.get("scheduler"), execution.get("scheduler_file"))
        if execution.get("workers"):
            from ..execution.pool import warm_up  # lazily

            warm_up()  # the fork server imports the solver while this process imports it and validates
        job = load()
        with progress.jobs(job.title, quiet, job.noun) as notify:
            finished = job.run(Execution(notify=notify, **execution))
        if as_json:
            output.emit(output.finished(job, finished.result))
        elif finished.table:
            typer.echo(finished.table)
        for warning in finished.warnings:
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(finished.summary)
        if finished.failures:
            raise fail(finished.failure_line(), 1)
