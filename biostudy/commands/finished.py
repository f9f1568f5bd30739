"""What a job command (sweep, convergence, stability, calibrate) has to say when its jobs are over."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from ..execution.jobs import Execution


@dataclass
class Finished:
    """The end of a job command: a summary line, the jobs that failed (any makes the exit status 1), a table
    for stdout, and warnings for stderr."""

    summary: str  # one line on stderr: what ran, what was written
    failures: dict[str, str]  # job -> why it failed
    total: int  # jobs in all
    table: str = ""  # printed on stdout
    noun: str = "cases"
    warnings: list[str] = field(default_factory=list)  # printed on stderr, before the summary
    result: object = None  # what the command made (a dataset, a report), for Python callers

    def failure_line(self) -> str:
        """'2 of 9 cases failed: a: why; b: why' (the first three)."""
        listed = "; ".join(f"{k}: {v}" for k, v in list(self.failures.items())[:3])
        return f"{len(self.failures)} of {self.total} {self.noun} failed: {listed}"


class JobCommand(Protocol):
    """A loaded, validated job command, nothing run yet: its progress title, what runs it, and the file it sums
    up in (study.nc, convergence.nc, ...: what the Python function returns)."""

    title: str
    noun: str

    @property
    def summary(self) -> Path: ...

    def run(self, execution: Execution) -> Finished: ...
