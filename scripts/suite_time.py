"""Time the test suite as CI runs it and write docs/measured/suite.md (the README includes it).

    python scripts/suite_time.py

Runs `python -m pytest -q --durations=12` in a fresh process, with the load
average before and after, and records the wall time, the count and the
slowest tests.  Measure on an idle machine: the README promises a time for
2 idle cores.
"""
from __future__ import annotations

import datetime
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "measured" / "suite.md"


def minutes(seconds: float) -> str:
    return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"


def main() -> None:
    before = os.getloadavg()[0]
    began = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "--durations=12", "-p", "no:cacheprovider"],
                          cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - began
    after = os.getloadavg()[0]
    summary = done.stdout.strip().splitlines()[-1]
    count = sum(int(n) for n in re.findall(r"(\d+) (?:passed|xfailed|failed|skipped)", summary))
    slowest = [line for line in done.stdout.splitlines() if re.match(r"^\d+\.\d+s (call|setup|teardown)", line)]
    OUT.write_text("\n".join([
        "# The test suite's time (scripts/suite_time.py)", "",
        f"tests: {count}", f"wall time: {minutes(wall)}", f"load average: {before:.1f} before, {after:.1f} after",
        f"measured: {datetime.date.today().isoformat()}", f"result: {summary}", "",
        "Slowest (pytest --durations):", "", "```", *slowest, "```", ""]), encoding="utf-8")
    print(OUT.read_text(encoding="utf-8"))
    sys.exit(done.returncode)


if __name__ == "__main__":
    main()
