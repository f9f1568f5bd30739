"""Progress on stderr: a rich bar on a terminal, plain lines where stderr is a file or a pipe.

A batch job, a cluster log or `| tee` gets one plain line each time another
tenth of the work is done or 30 s have passed, with no escape codes (`Lines`).
The consoles are made when first used, not at import: a test (or a notebook)
that redirects stderr gets what it redirected to.
"""
from __future__ import annotations

import contextlib
import logging
import sys
import time as clock
from functools import lru_cache
from typing import TYPE_CHECKING

from ..formatting import UNCUT
from . import logs
from .pace import SHORTEST, Mark, Work, time_left

detail = logging.getLogger("biostudy.cli")  # each job's end with -v (`logs`)

if TYPE_CHECKING:
    from rich.console import Console




@lru_cache(maxsize=None)
def _console(stderr: bool, stream_id: int) -> Console:
    """soft_wrap: a long message stays one line in a log.  Not a terminal (a pipe, a file, a batch log):
    tables as wide as their content, never cut to 80 columns ('17…'); rich pads a table's lines to the
    table's own width, not the console's.  Full width rather than TSV: the same table as on a terminal,
    and `--json` is the form for programs."""
    from rich.console import Console  # rich when first printed to: `--version` and `-h` do not pay for it

    console = Console(stderr=stderr, soft_wrap=True)
    if not console.is_terminal:
        console.width = UNCUT
    return console


def err() -> Console:
    """The console on this process's stderr (a new one when stderr was replaced)."""
    return _console(True, id(sys.stderr))


def out() -> Console:
    return _console(False, id(sys.stdout))


class Lines:
    """Progress for a log: one plain line each time another `EVERY` of the work is done or `SECONDS` have
    passed since the last line: what is done, the counts, the time elapsed and the time left (`pace`)."""

    EVERY = 0.1
    SECONDS = 30.0

    def __init__(self, title: str, total: float):
        self.title, self.total = title, total
        self.began = self.last_time = clock.monotonic()
        self.last_done = 0.0
        self.first: Mark | None = None  # at the first report

    def update(self, done: float, position: str, counts: str, force: bool = False, work: Work | None = None
               ) -> None:
        """`work`: a run's steps, mechanics solves and outputs, which the time left prices apart (`pace`)."""
        now = clock.monotonic()
        mark = Mark(now, done, work or Work())
        if self.first is None:
            self.first = mark
        fraction = done / self.total if self.total else 1.0
        if not (force or fraction - self.last_done >= self.EVERY - 1e-12 or now - self.last_time >= self.SECONDS
                or (fraction >= 1.0 > self.last_done)):
            return
        self.last_done, self.last_time = fraction, now
        elapsed = now - self.began
        left = time_left(self.first, mark, self.total)
        left_text = f", left {about(left)}" if left is not None else ""
        print(f"{self.title}: {position} ({fraction:.0%}), {counts}, elapsed {duration(elapsed)}{left_text}",
              file=sys.stderr, flush=True)


def about(seconds: float) -> str:
    """~12.3 s; <1 s under `pace.SHORTEST`, where what no estimate prices (files opened and closed, the exit)
    outweighs what it does."""
    return f"<{SHORTEST:g} s" if seconds < SHORTEST else f"~{duration(seconds)}"


def duration(seconds: float) -> str:
    """12.3 s, 4 min 05 s, 2 h 03 min."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    minutes = int(seconds // 60)
    if minutes < 60:
        return f"{minutes} min {int(seconds % 60):02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


@contextlib.contextmanager
def simulation(name: str, t_end: float, quiet: bool):
    """Progress of one simulation: simulated time, steps and bisections; yields the solver's callback."""
    console = err()
    quiet = quiet or logs.is_quiet()
    if not quiet and not console.is_terminal:
        lines = Lines(name, t_end)
        yield lambda p: lines.update(p.time, f"T* = {p.time:.4g} / {t_end:g}",
                                     f"steps {p.steps}, bisections {p.bisections}",
                                     work=Work(p.steps, p.mechanics_seconds, p.mechanics_solves, p.mechanics_left,
                                               p.outputs, p.output_seconds))
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn("[bold]{task.description}"), BarColumn(),
               TextColumn("T* = {task.completed:.4g} / {task.total:g}"), TextColumn("steps {task.fields[steps]}"),
               TextColumn("bisections {task.fields[bisections]}"), TimeElapsedColumn())
    with Progress(*columns, console=console, disable=quiet) as progress:
        task = progress.add_task(name, total=t_end, steps=0, bisections=0)
        yield lambda p: progress.update(task, completed=p.time, steps=p.steps, bisections=p.bisections)


@contextlib.contextmanager
def jobs(title: str, quiet: bool, noun: str = "cases"):
    """Progress over the jobs of a sweep, convergence, stability or calibration run; yields `run_jobs`'
    notify.  A job that fails is told at once (also with --quiet): the others go on; so is a note (event
    "note": no workers on a Dask scheduler, say).  The bar shows from the
    first job on: input found bad before (an output directory in use, say) is told on its own line.  When
    every job had finished before, it says so instead of showing an empty bar."""
    console = err()
    quiet = quiet or logs.is_quiet()
    counts = {"start": 0, "skip": 0, "failed before": 0, "finished": 0, "failed": 0}
    lines = None if quiet or console.is_terminal else Lines(title, 0)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                        TextColumn("{task.fields[last]}"), TimeElapsedColumn(), console=console,
                        disable=quiet or lines is not None)
    task = progress.add_task(title, total=0, last="", visible=False)
    try:
        def notify(event: str, job_id: str, message: str):
            if not progress.live.is_started:
                progress.start()
            if event == "note":  # something to know while waiting (no workers): also with --quiet
                progress.console.print(message, markup=False, highlight=False)
            elif event == "skip":
                counts["skip"] += 1
                counts["failed before"] += message == "failed"
                detail.debug("%s skipped: %s before", job_id, message)
            elif event == "start":
                counts["start"] += 1
                progress.update(task, total=counts["start"], visible=True)
            elif event in ("done", "failed"):
                detail.debug("%s %s%s", job_id, event, f": {message}" if message and event == "done" else "")
                counts["finished"] += 1
                counts["failed"] += event == "failed"
                progress.update(task, advance=1, last=f"{job_id} {event}")
                if event == "failed":
                    progress.console.print(f"{job_id} failed: {message}", markup=False, highlight=False)
                if lines is not None:
                    lines.total = counts["start"]
                    lines.update(counts["finished"], f"{counts['finished']}/{counts['start']} {noun}",
                                 f"{counts['failed']} failed, last {job_id} {event}", force=event == "failed")

        yield notify
    finally:
        if progress.live.is_started:
            progress.stop()
    if counts["start"] == 0 and counts["skip"]:
        again = (f", {counts['failed before']} of them failed (--retry-failed runs them again)"
                 if counts["failed before"] else "")
        console.print(f"nothing to run: all {counts['skip']} {noun} finished before{again}")
