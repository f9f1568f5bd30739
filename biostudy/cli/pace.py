"""The time left of a run or a sweep, from how the work went since the first report (`time_left`).

Not the pace since the start: what comes before the first report (importing
FiPy, building the mesh and the matrices, starting a pool) is paid once, and
counting it made the estimate at a tenth done 3-9 times too long
(benchmarks/time_left.py).  A run's mechanics solves come in lumps at
outputs (every few, the last always), not in proportion to simulated time:
they are counted apart, at their mean cost since the first report.  The
solve at the start (no growth yet to carry) costs next to nothing and says
nothing about the others, so until one has been timed the estimate names
how many are still to come instead of guessing their cost.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

Lumps = Tuple[float, int, int]  # work in lumps: seconds so far, how many done, how many to come


@dataclass(frozen=True)
class Mark:
    """Where the work stood at one moment: wall time, work done, and the lumps (seconds, done, to come)."""

    time: float
    done: float
    lump_seconds: float = 0.0
    lumps_done: int = 0
    lumps_left: int = 0


@dataclass(frozen=True)
class Left:
    """The time left: seconds, and lumps still to come whose cost is not known yet (not in `seconds`)."""

    seconds: float
    unpriced: int = 0


def time_left(first: Mark | None, now: Mark, total: float) -> Left | None:
    """The steady work at its pace since `first`, plus the lumps to come at their mean cost since `first`;
    None before there is a pace (at the first report) and when the work is done."""
    if first is None or not 0 < now.done < total or now.done <= first.done:
        return None
    lumps_timed = now.lumps_done - first.lumps_done
    lump_seconds = now.lump_seconds - first.lump_seconds
    steady = (now.time - first.time - lump_seconds) * (total - now.done) / (now.done - first.done)
    if not now.lumps_left or lumps_timed:
        return Left(steady + (lump_seconds / lumps_timed * now.lumps_left if now.lumps_left else 0.0))
    return Left(steady, now.lumps_left)
