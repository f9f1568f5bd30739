"""The time left of a run or a sweep: each kind of work still to come at what it has cost so far (`time_left`).

A run has three kinds of work, priced apart because they do not come in
proportion to one another:

* **steps**, at their pace since the first report.  Not the pace since the
  start: what comes before the first report (importing FiPy, building the
  mesh and the matrices, starting a pool) is paid once, and counting it made
  the estimate at a tenth done 3-9 times too long.
* **mechanics solves**, which come in lumps at outputs (every few, the last
  always), not in proportion to simulated time: the solver tells how many are
  done and still to come, and their wall time.  Those to come cost what those
  timed since the first report cost on average.
* **the finish**, after the last step: the dataset made from every output's
  fields, its observables, the file written.

What has not happened yet has no cost of its own to go by: the finish
(once, at the end), and the solves before the first one after the start
(the solve at the start, with no growth yet to carry, costs next to nothing
and says nothing about the others; in the bundled 3-D scenes the next comes
at a fifth done).  Both are priced in steps, at the steps' own cost in this
run, which scales with the cells and with the machine as they do: a solve at
`SOLVE_STEPS` steps, the finish at `FINISH_STEPS` steps per output (it passes
over each output's fields a few times, as a step passes over the cells).
benchmarks/time_left.py measures both ratios on the bundled scenes and how
close the estimate comes (docs/measured/time-left.txt).

A few tenths of a second (opening and closing files, the interpreter's exit)
are in no price: a line says "left <1 s" rather than a figure those would
dwarf.
"""
from __future__ import annotations

from dataclasses import dataclass, field

SOLVE_STEPS = 80.0  # a mechanics solve not timed yet, in steps (module docstring)
FINISH_STEPS = 5.0  # the finish's cost per output, in steps (module docstring)
SHORTEST = 1.0  # seconds: under this, a line says "<1 s" (module docstring)


@dataclass(frozen=True)
class Work:
    """What a run has done besides its simulated time: steps, mechanics solves (their wall time, how many done,
    how many still to come) and how many outputs its dataset holds.  A sweep's jobs have none of these."""

    steps: int = 0
    solve_seconds: float = 0.0
    solves_done: int = 0
    solves_left: int = 0
    outputs: int = 0


@dataclass(frozen=True)
class Mark:
    """Where the work stood at one moment: wall time, work done (simulated time or jobs) and the rest."""

    time: float
    done: float
    work: Work = field(default_factory=Work)


def time_left(first: Mark | None, now: Mark, total: float) -> float | None:
    """Seconds left: steps, solves and finish to come, each at its cost since `first` (module docstring); None
    before there is a pace (at the first report) and when nothing is left."""
    if first is None or not 0 < now.done <= total or now.done <= first.done:
        return None
    before, work = first.work, now.work
    solve_seconds = work.solve_seconds - before.solve_seconds
    solves_timed = work.solves_done - before.solves_done
    step_seconds = now.time - first.time - solve_seconds
    steps_taken = work.steps - before.steps
    step = step_seconds / steps_taken if steps_taken else 0.0  # one step's cost: the yardstick of the unseen
    solve = solve_seconds / solves_timed if solves_timed else SOLVE_STEPS * step
    left = (step_seconds * (total - now.done) / (now.done - first.done) + solve * work.solves_left
            + FINISH_STEPS * work.outputs * step)
    return left if left > 0 else None
