"""Time the test suite as CI runs it and write docs/measured/suite.md (the README includes it).

    python scripts/suite_time.py

Runs `python -m pytest -q --durations=0` in a fresh process, with the load
average before and after, and records the wall time, the count, the slowest
tests and each file's summed seconds (`--dist loadfile` keeps a file on one
of the two workers: no file may take much more than half the wall time).
Measure on an idle machine: the README promises a time for 2 idle cores.  On
a busy one compare CPU seconds instead (`scripts/suite_cost.py`).
"""
from __future__ import annotations

import datetime
import os
import re
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "measured" / "suite.md"


def minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"


HOW = """\
How it is measured: `python scripts/suite_time.py` on the idle 2-core machine (the wall time above, which the
README quotes: `scripts/docs_sync.py`).  The seconds below are pytest's `--durations` (wall time of each setup,
call and teardown); a file's are summed, and `--dist loadfile` runs a file on one worker, so a file near half the
wall time sets it.  On a busy machine wall times are not comparable (at a load average of 10, several times the idle
ones): compare the CPU seconds of the same tests before and after a change instead,
`PYTHONPATH=$PWD:$PWD/scripts python -m pytest -n 0 -p suite_cost tests/test_x.py` (`scripts/suite_cost.py`:
each test's and its children's user + system time, summed per file).
"""


def per_file(lines: list[str]) -> list[tuple[float, str]]:
    """Seconds summed per test file from `--durations` lines ('1.23s call     tests/test_x.py::name'), largest
    first."""
    files: dict[str, float] = defaultdict(float)
    for line in lines:
        seconds, _, test = line.split(maxsplit=2)
        files[test.split("::", 1)[0]] += float(seconds.rstrip("s"))
    return sorted(((seconds, name) for name, seconds in files.items()), reverse=True)


def main() -> None:
    before = os.getloadavg()[0]
    began = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "--durations=0", "--durations-min=0", "-p",
                           "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - began
    after = os.getloadavg()[0]
    summary = done.stdout.strip().splitlines()[-1]
    count = sum(int(n) for n in re.findall(r"(\d+) (?:passed|xfailed|failed|skipped)", summary))
    slowest = [line for line in done.stdout.splitlines() if re.match(r"^\d+\.\d+s (call|setup|teardown)", line)]
    failed = [line for line in done.stdout.splitlines() if line.startswith(("FAILED ", "ERROR "))]
    OUT.write_text("\n".join([
        "# The test suite's time (scripts/suite_time.py)", "",
        f"tests: {count}", f"wall time: {minutes(wall)}", f"load average: {before:.1f} before, {after:.1f} after",
        f"measured: {datetime.date.today().isoformat()}", f"result: {summary}", *failed, "",
        HOW, "Slowest (pytest --durations):", "", "```", *slowest[:12], "```", "",
        "Per file (seconds summed over its tests):", "", "```",
        *(f"{seconds:7.1f}s {name}" for seconds, name in per_file(slowest)), "```", ""]), encoding="utf-8")
    print(OUT.read_text(encoding="utf-8"))
    sys.exit(done.returncode)


if __name__ == "__main__":
    main()
