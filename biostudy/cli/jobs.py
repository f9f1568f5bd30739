"""The command line's side of every job command (sweep, convergence, stability, calibrate): progress and print."""
from __future__ import annotations

from typing import Any

import typer

from ..commands.options import Command
from . import output, progress
from .guard import fail, guarded


def job_command(declared: Command, options: dict[str, Any], quiet: bool, as_json: bool = False) -> None:
    """Start the job (`commands.jobs.started`: bad input is exit 2 before anything runs), run it with a progress
    display, and say what came of it (`commands.finished.Finished`).  A job that failed, or a pool that broke
    down, is exit status 1.  `as_json`: the result as JSON on stdout instead of the table (`output.finished`).
    """
    with guarded():
        from ..commands.jobs import started  # lazily: --version and -h pay for no execution machinery

        job, where = started(declared, options)  # first: it starts the workers' fork server before the imports below
        from ..execution.jobs import Execution
        with progress.jobs(job.title, quiet, job.noun) as notify:
            finished = job.run(Execution(notify=notify, **where))
        if as_json:
            output.emit(output.finished(job, finished.result))
        elif finished.table:
            typer.echo(finished.table)
        for warning in finished.warnings:
            typer.echo(f"warning: {warning}", err=True)
        progress.err().print(finished.summary)
        if finished.failures:
            raise fail(finished.failure_line(), 1)
