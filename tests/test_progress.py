"""Progress lines for logs (`biostudy.cli.progress.Lines`) and their time-left estimate (`cli.pace`), on
synthetic runs with a fake clock: a start-up cost, steady steps, mechanics solves at outputs, the finish."""
from __future__ import annotations

import re

import pytest

from biostudy.cli import pace, progress


def synthetic_run(step: float, solve: float, steps: int = 100, every: int = 10, start: float = 5.0):
    """(mark, seconds truly left) at every step of a run timed by a fake clock: `start` s before the first step,
    steps of `step` s, an output after every `every`-th step with a mechanics solve of `solve` s, one more
    (next to free) at the start, and the finish at the end at `pace.FINISH_STEPS` steps per output."""
    outputs = steps // every + 1
    now, solved, solves_done, solves_left = start, 0.01, 1, outputs - 1
    marks = []
    for taken in range(1, steps + 1):
        now += step
        marks.append(pace.Mark(now, float(taken), pace.Work(taken, solved, solves_done, solves_left, outputs)))
        if taken % every == 0:
            now += solve
            solved, solves_done, solves_left = solved + solve, solves_done + 1, solves_left - 1
    end = now + pace.FINISH_STEPS * outputs * step
    return [(mark, end - mark.time) for mark in marks]


def test_solves_at_outputs_are_priced_by_what_they_cost():
    """Output steps whose solve costs 10 plain steps: once one solve after the start has been timed, every
    estimate is the time truly left: steps, solves and finish (the estimate before this one left the finish
    out: 3.0 s at 90 % of 8.5 s left)."""
    run = synthetic_run(step=0.1, solve=1.0)
    for mark, truly_left in run[10:]:  # from the step after the first solve on
        assert pace.time_left(run[0][0], mark, 100.0) == pytest.approx(truly_left), mark


def test_solves_not_timed_yet_are_priced_in_steps():
    """Before the first solve after the start, those to come cost `SOLVE_STEPS` steps each: a run whose
    solves cost that is priced exactly from the first estimate on (the estimate before this one said 9.0 s
    and named the 10 solves, of 94.5 s left at 10 %)."""
    run = synthetic_run(step=0.1, solve=0.1 * pace.SOLVE_STEPS)
    for mark, truly_left in run[1:]:
        assert pace.time_left(run[0][0], mark, 100.0) == pytest.approx(truly_left), mark


@pytest.mark.parametrize("start", [0.0, 10.0, 60.0])
def test_the_start_up_is_not_paced(start):
    """A fixed start-up cost (imports, assembly) before steady steps: it is paid once, and the estimate at a
    tenth is the time truly left (pacing from the start said 11x too long with 10 s)."""
    run = synthetic_run(step=0.1, solve=0.1 * pace.SOLVE_STEPS, start=start)
    mark, truly_left = run[9]
    assert pace.time_left(run[0][0], mark, 100.0) == pytest.approx(truly_left)


def test_time_left_needs_a_pace():
    """No estimate at the first report (no pace yet), none when nothing is left; a run's finish and last solve
    are left after its last step."""
    first = pace.Mark(5.0, 1.0)
    assert pace.time_left(None, pace.Mark(5.0, 1.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(5.0, 1.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(9.0, 10.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(7.0, 3.0), 10.0) == 7.0
    run = synthetic_run(step=0.1, solve=1.0)
    last, truly_left = run[-1]
    assert truly_left > 1.0 and pace.time_left(run[0][0], last, 100.0) == pytest.approx(truly_left)


def test_outputs_handed_over_in_the_loop_are_no_step_of_the_finish():
    """Issue 39.9: a streamed run writes each output to its spool between steps (here 45 of every 100 ms, as the
    32³ run of 101 outputs did); its finish costs `FINISH_STEPS` steps without that per output, and priced in
    whole loop steps it came out 3-4 times too long ('~15.9 s' at 100 % with 6.6 s left)."""
    step, spooled, outputs = 0.055, 0.045, 101
    now, marks = 2.0, []
    for taken in range(1, 101):  # an output after every step
        now += step + spooled
        marks.append(pace.Mark(now, float(taken), pace.Work(taken, 0.0, 0, 0, outputs, spooled * taken)))
    end = now + pace.FINISH_STEPS * outputs * step
    for mark in marks[1:]:
        assert pace.time_left(marks[0], mark, 100.0) == pytest.approx(end - mark.time), mark


def _lines(monkeypatch, capsys, run) -> list[str]:
    """The lines `Lines` prints for a synthetic run."""
    monkeypatch.setattr(progress.clock, "monotonic", lambda: now)
    now = 0.0
    lines = progress.Lines("synthetic", 100.0)
    for mark, _ in run:
        now = mark.time
        lines.update(mark.done, f"step {mark.done:g}", "", work=mark.work)
    return capsys.readouterr().err.splitlines()


def test_lines_print_the_time_left_each_tenth(monkeypatch, capsys):
    """One line a tenth; the last (100 %) with what is left after the last step: the last solve and the finish."""
    printed = _lines(monkeypatch, capsys, synthetic_run(step=0.1, solve=1.0))
    assert [re.search(r"\((\d+)%\)", line)[1] for line in printed] == [str(10 * n) for n in range(1, 11)]
    assert printed[-1].endswith(f"left ~{1.0 + pace.FINISH_STEPS * 11 * 0.1:.1f} s"), printed[-1]


def test_under_a_second_is_said_so(monkeypatch, capsys):
    """A few tenths of a second are in no price (files, the exit): under `SHORTEST` the line says "<1 s"."""
    printed = _lines(monkeypatch, capsys, synthetic_run(step=0.0005, solve=0.0005 * pace.SOLVE_STEPS))
    assert all(line.endswith("left <1 s") for line in printed[1:]), printed
