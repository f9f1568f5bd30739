"""How close the progress lines' time left comes to the time really left, on the bundled scenes as a user runs them.

Each scene runs as `biostudy run NAME -o ...` (its default size) with stderr a
pipe, so progress comes as plain lines (`biostudy.cli.progress.Lines`), each
timed as it arrives.  At 10, 20, 30, 50, 70 and 90 % done (the first line at or
past it) the table gives the line's estimate, the time really left (from that
line to the end of the process: the file written, the interpreter gone) and
the relative error |estimate - truth| / truth; a line that says "<1 s" is wrong
only by what the truth exceeds 1 s.  The issue's bar: within 50 % from a tenth
done on.  "100 %" is the last step's line: what is left then is the last
mechanics solve and the finish (the dataset made, its observables, the file
written); "exit" is the time from the result's line ("wrote ...") to the
process's end.

Below each scene, what `biostudy.cli.pace` prices in steps, as the run's own
dataset measures it: a step (the time loop's wall time less the mechanics,
per step, from the first output to the last), a mechanics solve after the start (in steps: `SOLVE_STEPS` is
the price before one is timed), and the finish per output (in steps:
`FINISH_STEPS`), which is the time after the last step's line less one
solve's mean and the exit.  The load average is the machine's before and
after each scene: on a shared machine, re-run a scene that others disturbed.

    python benchmarks/time_left.py [--scene NAME [--set KEY=VALUE ...]]...
"""
from __future__ import annotations

import argparse
import datetime
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from biostudy.cli import pace
from biostudy.inputs import bundled

CHECKS = (10, 20, 30, 50, 70, 90, 100)
LINE = re.compile(r"T\* = [\d.e+-]+ / [\d.e+-]+ \((\d+)%\).*?(?:, left (~.+|<1 s))?$")


def seconds(text: str) -> float:
    """'~12.3 s', '~4 min 05 s', '~2 h 03 min' (`progress.duration`) -> seconds."""
    found = dict((unit, float(n)) for n, unit in re.findall(r"([\d.]+) (h|min|s)\b", text))
    return 3600 * found.get("h", 0) + 60 * found.get("min", 0) + found.get("s", 0)


def error(estimate: str, truth: float) -> float:
    """Relative error of a printed estimate; "<1 s" is wrong only by what the truth exceeds 1 s."""
    if estimate.startswith("<"):
        return max(0.0, truth - pace.SHORTEST) / truth
    return abs(seconds(estimate) - truth) / truth


def measure(scene: str, overrides: list[str]) -> dict:
    """Run the scene; every progress line with its arrival, the result line's arrival, the end, the dataset's
    own timings."""
    with tempfile.TemporaryDirectory() as directory:
        out = Path(directory) / "run.nc"
        command = ["nice", sys.executable, "-m", "biostudy", "run", scene, "-o", str(out), *overrides]
        load = os.getloadavg()[0]
        began = time.monotonic()
        child = subprocess.Popen(command, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
        assert child.stderr is not None
        lines, wrote = [], None
        for line in child.stderr:
            match = LINE.search(line.strip())
            if match:
                lines.append((time.monotonic(), int(match[1]), match[2] or ""))
            elif line.startswith("wrote "):
                wrote = time.monotonic()
        child.wait()
        ended = time.monotonic()
        if child.returncode or not lines or wrote is None:
            raise SystemExit(f"{scene}: exit {child.returncode}, {len(lines)} progress lines")
        with xr.open_dataset(out) as ds:
            attrs = dict(ds.attrs)
            space = [dim for dim in ds.phi.dims if dim != "time"]
            solves = int(np.count_nonzero(ds.p.notnull().any(space))) if "p" in ds else 0  # the outputs with u, p
            outputs, elapsed = ds.sizes["time"], ds.elapsed.values
    return {"lines": lines, "wrote": wrote, "ended": ended, "began": began, "load": (load, os.getloadavg()[0]),
            "attrs": attrs, "solves": solves, "outputs": outputs, "loop": elapsed[-1] - elapsed[0]}


def report(scene: str, run: dict) -> None:
    ended, lines = run["ended"], run["lines"]
    print(f"\n{scene} (load average {run['load'][0]:.2f} before, {run['load'][1]:.2f} after; "
          f"{ended - run['began']:.1f} s in all)")
    print(f"{'done':>5} {'at s':>7} {'estimate':>12} {'truth s':>8} {'error':>6}")
    for check in CHECKS:
        at, percent, estimate = next(line for line in lines if line[1] >= check)
        truth = ended - at
        text = estimate.lstrip("~") if estimate else "-"
        shown = f"{error(estimate, truth):6.2f}" if estimate else f"{'-':>6}"
        print(f"{percent:>4}% {at - run['began']:>7.1f} {text:>12} {truth:>8.2f} {shown}")
    attrs = run["attrs"]
    mechanics = attrs.get("wall_time_mechanics", 0.0)
    step = (run["loop"] - mechanics) / attrs["steps_taken"]  # from the first output (the set-up done) to the last
    solve = mechanics / (run["solves"] - 1) if run["solves"] > 1 else 0.0  # the one at the start is next to free
    exit_seconds = ended - run["wrote"]
    finish = ended - lines[-1][0] - solve - exit_seconds
    print(f"exit {exit_seconds:.2f} s; a step {1e3 * step:.2f} ms; "
          + (f"a mechanics solve {solve:.2f} s = {solve / step:.0f} steps; " if solve else "")
          + f"the finish {finish:.2f} s = {finish / step / run['outputs']:.1f} steps per output "
          f"({run['outputs']} outputs)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", action="append", default=[], help="a bundled scene (default: all, "
                                                                     "each at its own size)")
    parser.add_argument("--set", action="append", default=[], help="override for every --scene")
    args = parser.parse_args()
    scenes = args.scene or [e.path.stem for e in bundled.entries() if e.kind == "scene"]
    overrides = [a for s in args.set for a in ("--set", s)]
    print(f"$ python benchmarks/time_left.py {' '.join(sys.argv[1:])}".rstrip()
          + f"   ({datetime.date.today()}, {os.cpu_count()} cores, SOLVE_STEPS {pace.SOLVE_STEPS:g}, "
            f"FINISH_STEPS {pace.FINISH_STEPS:g})")
    for scene in scenes:
        report(scene, measure(scene, overrides))


if __name__ == "__main__":
    main()
