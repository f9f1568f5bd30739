"""Progress lines for logs (`biostudy.cli.progress.Lines`) and their time-left estimate (`cli.pace`), on
synthetic timelines (a fake clock): a start-up cost, steady steps, mechanics solves in lumps."""
from __future__ import annotations

import re

import pytest

from biostudy.cli import pace, progress


def _lines_of(monkeypatch, capsys, timeline) -> list[tuple[int, str]]:
    """Feed (wall time, done of 100, lumps) to `Lines`; the printed lines with their percentage."""
    now = [0.0]
    monkeypatch.setattr(progress.clock, "monotonic", lambda: now[0])
    lines = progress.Lines("synthetic", 100.0, "mechanics solves")
    for when, done, lumps in timeline:
        now[0] = when
        lines.update(done, f"step {done:g}", "", lumps=lumps)
    printed = capsys.readouterr().err.splitlines()
    return [(int(re.search(r"\((\d+)%\)", line)[1]), line) for line in printed]


def _estimate(line: str) -> float:
    return float(re.search(r"left ~([\d.]+) s", line)[1])


@pytest.mark.parametrize("start_cost", [0.0, 10.0, 60.0])
def test_time_left_at_a_tenth_is_within_half_of_the_truth(start_cost, monkeypatch, capsys):
    """A fixed start-up cost (imports, assembly) before steady steps of 0.1 s: the estimate printed at 10 %
    or just after is within 50 % of the time really left (pacing from the start said 11x too long with 10 s)."""
    timeline = [(start_cost + 0.1 * step, float(step), (0.0, 0, 0)) for step in range(1, 21)]
    done, line = next((d, line) for d, line in _lines_of(monkeypatch, capsys, timeline) if d >= 10)
    truly_left = 0.1 * (100 - done)
    assert abs(_estimate(line) - truly_left) <= 0.5 * truly_left, line


def test_time_left_counts_the_mechanics_solves_to_come(monkeypatch, capsys):
    """Steps of 0.1 s, a solve of 1 s after every 5th step, the one at the start next to free: at a tenth done
    the solves to come are most of the time left (the steps' pace alone said 9 s of 27 s)."""
    timeline, now, solved = [], 5.01, (0.01, 1, 20)
    for step in range(1, 21):
        now += 0.1
        timeline.append((now, float(step), solved))
        if step % 5 == 0:
            now += 1.0
            solved = (solved[0] + 1.0, solved[1] + 1, solved[2] - 1)
    done, line = next((d, line) for d, line in _lines_of(monkeypatch, capsys, timeline) if d >= 10)
    truly_left = 0.1 * (100 - done) + 1.0 * (100 - done) / 5
    assert abs(_estimate(line) - truly_left) <= 0.5 * truly_left, line


def test_solves_not_timed_yet_are_named_not_guessed(monkeypatch, capsys):
    """Before any solve after the start has been timed, the line says how many are to come."""
    timeline = [(5.0 + 0.1 * step, float(step), (0.01, 1, 5)) for step in range(1, 11)]
    line = _lines_of(monkeypatch, capsys, timeline)[-1][1]
    assert re.search(r"left ~[\d.]+ s \+ 5 mechanics solves$", line), line


def test_time_left_needs_a_pace():
    """No estimate at the first report (no pace yet), none when done."""
    first = pace.Mark(5.0, 1.0)
    assert pace.time_left(None, pace.Mark(5.0, 1.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(5.0, 1.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(9.0, 10.0), 10.0) is None
    assert pace.time_left(first, pace.Mark(7.0, 3.0), 10.0) == pace.Left(7.0)
