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

Outputs handed over during the loop (a streamed run writes each to its spool:
`solver.Progress.output_seconds`) cost the loop time in proportion to
simulated time, as steps do, but they are no step's cost: the yardstick of
the unseen is a step without them.  A run of 32³ cells streaming 101 outputs
over 100 steps spent 45 of every 105 ms of a step on its output, and priced
in such steps its finish came out 3-4 times too long (issue 39).

What has not happened yet has no cost of its own to go by: the finish
(once, at the end), and the solves before the first one after the start
(the solve at the start, with no growth yet to carry, costs next to nothing
and says nothing about the others; in the bundled 3-D scenes the next comes
at a fifth done).  Both are priced in steps, at the steps' own cost in this
run, which scales with the cells and with the machine as they do: a solve at
`SOLVE_STEPS` steps, the finish at `FINISH_STEPS` steps per output (it passes
over each output's fields a few times, as a step passes over the cells:
measured 2.4-4.2 on the bundled 3-D scenes, 2.7 on the 32³ run streaming 101
outputs, each a step without its output's spooling).
benchmarks/time_left.py measures both ratios on the bundled scenes and how
close the estimate comes (docs/measured/time-left.txt).

A few tenths of a second (opening and closing files, the interpreter's exit)
are in no price: a line says "left <1 s" rather than a figure those would
dwarf.
"""
from __future__ import annotations

from dataclasses import dataclass, field

SOLVE_STEPS = 80.0  # a mechanics solve not timed yet, in steps (module docstring)
FINISH_STEPS = 3.0  # the finish's cost per output, in steps (module docstring)
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
    output_seconds: float = 0.0  # spent handing outputs over in the loop (`solver.Progress.output_seconds`)


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
    loop_seconds = now.time - first.time - solve_seconds  # steps and the outputs handed over between them
    steps_taken = work.steps - before.steps
    output_seconds = work.output_seconds - before.output_seconds
    step = (loop_seconds - output_seconds) / steps_taken if steps_taken else 0.0  # the yardstick of the unseen
    solve = solve_seconds / solves_timed if solves_timed else SOLVE_STEPS * step
    left = (loop_seconds * (total - now.done) / (now.done - first.done) + solve * work.solves_left
            + FINISH_STEPS * work.outputs * step)
    return left if left > 0 else None
