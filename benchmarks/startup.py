"""How long the `biostudy` command takes to start: --version, -h, scenes, and show of a small run's file.

Each command is started as a fresh process `--runs` times (after one run not
counted); the table prints the median wall time and the load average at the
start.  The small file is a 16 x 16 run of 20 steps without mechanics, made
first in a temporary directory.  The issue's bar is well under half a second
on an idle machine (issue 19, item 6): the command line imports FiPy, Dask,
matplotlib, scikit-image, pydantic and xarray only in the commands that need
them, and `show` of a run's file reads it with netCDF4 alone
(`biostudy.reports.glance`).

    python benchmarks/startup.py [--runs 7]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENE = """\
name = "small"
[grid]
shape = [16, 16]
[time]
t_end = 0.1
steps = 20
outputs = 3
[[biofilm]]
shape = "sphere"
center = [8.0, 8.0]
radius = 3.0
[[nutrient]]
shape = "box"
lower = [14.0, 14.0]
upper = [16.0, 16.0]
"""


def biostudy() -> list[str]:
    """The installed command beside this interpreter (what a user types), else `python -m biostudy`."""
    script = Path(sys.executable).with_name("biostudy")
    return [str(script)] if script.exists() else [sys.executable, "-m", "biostudy"]


def timed(command: list[str], runs: int, cwd: Path) -> tuple[float, float, float]:
    """(median, min, max) wall seconds of `runs` fresh processes, after one that is not counted."""
    seconds = []
    for i in range(runs + 1):
        began = time.perf_counter()
        subprocess.run(command, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        if i:
            seconds.append(time.perf_counter() - began)
    return statistics.median(seconds), min(seconds), max(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    args = parser.parse_args()
    command = biostudy()
    with tempfile.TemporaryDirectory() as folder:
        cwd = Path(folder)
        (cwd / "small.toml").write_text(SCENE)
        subprocess.run([*command, "run", "small.toml", "-o", "small.nc", "-q"], cwd=cwd, check=True,
                       stderr=subprocess.DEVNULL)
        print(f"start-up of {' '.join(Path(c).name for c in command)} (median of {args.runs} fresh processes)")
        print(f"{'command':<28} {'median s':>9} {'min s':>7} {'max s':>7} {'load':>6}")
        for label, extra in (("--version", ["--version"]), ("-h", ["-h"]), ("scenes", ["scenes"]),
                             ("show small.nc", ["show", "small.nc"])):
            load = os.getloadavg()[0]
            median, low, high = timed([*command, *extra], args.runs, cwd)
            print(f"{'biostudy ' + label:<28} {median:9.3f} {low:7.3f} {high:7.3f} {load:6.2f}")


if __name__ == "__main__":
    main()
