"""What a study costs beyond its simulations, and what workers gain (issue 35, item 1): prints tables.

    python benchmarks/sweep.py                          # every part, ~6 min on 2 quiet cores
    python benchmarks/sweep.py --only service --repeats 3
    python benchmarks/sweep.py --only speedup --repeats 3
    python benchmarks/sweep.py --only speedup --steps 800 --repeats 2     # cases of ~0.6 s instead of ~0.13 s
    python benchmarks/sweep.py --only calibration
    python benchmarks/sweep.py --only combine --cases 1000 --repeats 3

Every sweep and calibration runs as a user runs it: a fresh `biostudy` process (`python -m biostudy ... -q`), its
start included, into a fresh directory; a figure of several repeats is their median.  The cases are small 2-D ones:
the bundled directional2d scene at 40 x 40 cells (h = 0.5 µm), 100 steps to T* = 0.1, 11 outputs, upwind, over
g x r (4 cases: 2 x 2; 36 cases: 6 x 6).

1. service: the service's own cost per case: a serial sweep's wall time beyond the cases' own (the sum of the
   simulations' wall times that study.nc records), differenced between the 36-case and the 4-case study so that
   the process's start and the first case's imports cancel: ((W36 - S36) - (W4 - S4)) / 32.  Bar: <= 0.1 s.
   The same in CPU seconds (the process's own beyond those of its simulations, counted around `worker.solve`),
   which a busy machine skews less; and the CPU seconds of the sweep's own process on 2 workers (what it does
   beyond scheduling).
2. speedup: the 36-case study serially and with `--workers 2` (the workers' start included).  Bar: >= 1.7x.
   `--steps N`: cases of N steps instead of 100 (the same dt, T* = N / 1000): how long a case must be for what
   every study pays once (~1.7 s) to leave the bar within reach.
   Beside it, the 4-case study the same two ways, and the speed-up of the 32 cases between them: what workers
   gain per case, with what is paid once per study (the process's start, each process's first case, study.nc)
   differenced away; and what that once costs serially (Amdahl: it bounds the whole study's speed-up).
3. calibration: `biostudy calibrate calibrate-agar` (least squares from 4 starts with profiles) serially and with
   `--workers 2`: wall time, simulations, and whether the estimates, standard errors and profile intervals are
   identical.  Bar: >= 1.6x, identical.
4. combine: study.nc of `--cases` cases (40 x 40, 11 outputs, 2 steps each: the sweep that makes them is not
   timed) written from the case files, in this process (`combine.write_study`; of `--repeats` runs, the one of
   median wall time), and where it goes: the case files read (`study_cases.Reader.read`), their fields copied
   into study.nc (`study_fill.fill`), the rest.  Bar: seconds, not minutes (issue 35: at most ~10 s for 1000).

"other processes" counts the CPU seconds the rest of the machine took meanwhile: a speed-up measured while they ran
is not the sweep's own.  With workers it includes the workers' own: they are children of multiprocessing's fork
server, which no one waits for, so their CPU time is nobody's child time here (subtract the cases' own wall time for a
rough figure of the rest).  Asserts nothing.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]
VALUES = {4: ([1e8, 1e9], [50.0, 200.0]),
          36: ([1e7, 3e7, 1e8, 3e8, 1e9, 3e9], [50.0, 70.0, 100.0, 140.0, 200.0, 280.0])}
SETTINGS = {"grid.shape": "[40, 40]", "grid.spacing": "0.5", "time.steps": "100", "time.t_end": "0.1",
            "time.outputs": "11", "numerics.advection": '"upwind"'}
# The command with the sweep process's own CPU seconds (not its workers') printed last on stderr.
MEASURED = """\
import json, os, resource, sys, time
os.environ.setdefault("FIPY_SOLVERS", "scipy")
from biostudy.cli import app
from biostudy.execution import worker  # light: the solver is imported when a case is first solved, as in `biostudy`

solve, spent = worker.solve, [0.0]


def timed(*args, **kwargs):
    began = time.process_time()
    try:
        return solve(*args, **kwargs)
    finally:
        spent[0] += time.process_time() - began


if __name__ == "__main__":
    worker.solve = timed  # the simulations run in this process (serially) are counted apart
    try:
        app(sys.argv[1:])
    finally:
        usage = resource.getrusage(resource.RUSAGE_SELF)
        print("cpu-self " + json.dumps([usage.ru_utime + usage.ru_stime, spent[0]]), file=sys.stderr)
"""


def load_average() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def write_study(directory: Path, cases: int, settings: dict = SETTINGS) -> Path:
    from biostudy.inputs import bundled

    shutil.copy(bundled.resolve("directional2d"), directory / "directional2d.toml")
    g, r = VALUES[cases] if cases in VALUES else ([1e8], [50.0 + 0.25 * i for i in range(cases)])
    fixed = "\n".join(f'"{key}" = {value}' for key, value in settings.items())
    path = directory / f"study{cases}.toml"
    path.write_text(f'name = "study{cases}"\nscene = "directional2d.toml"\n[set]\n{fixed}\n'
                    f'[sweep]\nmode = "grid"\n"params.g" = {g}\n"params.r" = {r}\n')
    return path


class Others:
    """CPU seconds that processes other than this one and its children used during a block."""

    def __enter__(self):
        self.start = self._now()
        return self

    def __exit__(self, *exc):
        self.seconds = self._now() - self.start

    @staticmethod
    def _now() -> float:
        busy = psutil.cpu_times()
        mine = os.times()
        system = busy.user + busy.system + busy.nice + getattr(busy, "irq", 0) + getattr(busy, "softirq", 0)
        own = mine.user + mine.system + mine.children_user + mine.children_system
        for process in psutil.Process().children(recursive=True):
            try:
                t = process.cpu_times()
                own += t.user + t.system + t.children_user + t.children_system
            except psutil.NoSuchProcess:
                pass
        return system - own


def command(directory: Path, *args: str) -> dict:
    """One `biostudy` command as a fresh process: its wall time, its own CPU seconds, other processes' CPU."""
    script = directory / "measured.py"
    script.write_text(MEASURED)
    began = time.perf_counter()
    with Others() as others:
        done = subprocess.run([sys.executable, str(script), *args, "-q"], capture_output=True, text=True)
    wall = time.perf_counter() - began
    if done.returncode:
        raise SystemExit(f"{' '.join(args)} failed:\n{done.stderr}")
    cpu, simulating = json.loads(next(line for line in done.stderr.splitlines() if line.startswith("cpu-self "))[9:])
    return {"wall": wall, "cpu": cpu, "cpu_simulating": simulating, "others": others.seconds}


def simulated(out: Path) -> float:
    """The sum of the cases' own wall times (the solver's), as study.nc records them."""
    import xarray as xr

    with xr.open_dataset(out / "study.nc") as ds:
        return float(ds["wall_time"].sum())


def sweeps(directory: Path, cases: int, workers: int | None, repeats: int, settings: dict = SETTINGS) -> list[dict]:
    study = write_study(directory, cases, settings)
    runs = []
    for repeat in range(repeats):
        out = directory / f"out-{cases}-{workers}-{repeat}"
        run = command(directory, "sweep", str(study), "-o", str(out), *(["--workers", str(workers)] if workers else []))
        run["simulated"] = simulated(out)
        shutil.rmtree(out)
        runs.append(run)
    return runs


def median(runs: list[dict], key: str) -> float:
    return statistics.median(run[key] for run in runs)


def service(directory: Path, repeats: int) -> list[tuple[str, float]]:
    four, many = sweeps(directory, 4, None, repeats), sweeps(directory, 36, None, repeats)
    per_case = [((b["wall"] - b["simulated"]) - (a["wall"] - a["simulated"])) / 32 for a, b in zip(four, many)]
    per_case_cpu = [((b["cpu"] - b["cpu_simulating"]) - (a["cpu"] - a["cpu_simulating"])) / 32
                    for a, b in zip(four, many)]
    on_two = sweeps(directory, 36, 2, repeats)
    return [("4 cases, serial: wall time (s)", median(four, "wall")),
            ("4 cases, serial: the cases' own wall time (s)", median(four, "simulated")),
            ("36 cases, serial: wall time (s)", median(many, "wall")),
            ("36 cases, serial: the cases' own wall time (s)", median(many, "simulated")),
            ("service's own cost per case (s)  [bar <= 0.1]", statistics.median(per_case)),
            ("  the same in CPU s (the process's beyond its simulations')", statistics.median(per_case_cpu)),
            ("36 cases, 2 workers: CPU s of the sweep's own process", median(on_two, "cpu")),
            ("36 cases, 2 workers: ... of which per case (s), beyond the 4-case run's",
             (median(on_two, "cpu") - median(sweeps(directory, 4, 2, repeats), "cpu")) / 32),
            ("CPU s used by other processes meanwhile (36 cases serial)", median(many, "others"))]


def stepped(steps: int) -> dict:
    """The cases' settings with `steps` steps of the same dt (T* = steps / 1000)."""
    return {**SETTINGS, "time.steps": str(steps), "time.t_end": repr(steps / 1000)}


def speedup(directory: Path, repeats: int, steps: int = 100) -> list[tuple[str, float]]:
    rows = []
    walls, fours = {}, {}
    for label, workers in (("serial", None), ("2 workers", 2)):
        runs = sweeps(directory, 36, workers, repeats, stepped(steps))
        walls[label] = median(runs, "wall")
        fours[label] = median(sweeps(directory, 4, workers, repeats, stepped(steps)), "wall")
        rows += [(f"36 cases, {label}: wall time (s)", walls[label]),
                 (f"36 cases, {label}: the cases' own wall time (s)", median(runs, "simulated")),
                 (f"36 cases, {label}: CPU s of the sweep's own process", median(runs, "cpu")),
                 (f"36 cases, {label}: CPU s used by other processes", median(runs, "others")),
                 (f"4 cases, {label}: wall time (s)", fours[label])]
    rows.append(("speed-up on 2 workers  [bar >= 1.7]", walls["serial"] / walls["2 workers"]))
    per_case = {label: (walls[label] - fours[label]) / 32 for label in walls}
    rows += [(f"per case beyond the 4-case study's, {label} (s)", per_case[label]) for label in walls]
    rows += [("  speed-up of the 32 cases beyond (the start, first cases and study.nc's own cancel)",
              per_case["serial"] / per_case["2 workers"]),
             ("  what is not shared: the serial study's wall time beyond 36 of its cases (s)",
              walls["serial"] - 36 * per_case["serial"])]
    return rows


ESTIMATES = ("estimate", "standard_error", "lower", "upper", "profile_")


def calibration(directory: Path, repeats: int) -> list[tuple[str, float]]:
    import numpy as np
    import xarray as xr

    rows, walls, found = [], {}, {}
    for label, workers in (("serial", None), ("2 workers", 2)):
        runs = []
        for repeat in range(repeats):
            out = directory / f"calibration-{workers}-{repeat}"
            runs.append(command(directory, "calibrate", "calibrate-agar", "-o", str(out),
                                *(["--workers", str(workers)] if workers else [])))
            with xr.open_dataset(out / "calibration.nc") as ds:
                found[label] = {name: ds[name].values.copy() for name in ds.data_vars
                                if any(name.startswith(e) for e in ESTIMATES)}
                runs[-1]["simulations"] = float(ds.attrs.get("simulations", np.nan))
            shutil.rmtree(out)
        walls[label] = median(runs, "wall")
        rows += [(f"calibrate-agar, {label}: wall time (s)", walls[label]),
                 (f"calibrate-agar, {label}: simulations", median(runs, "simulations")),
                 (f"calibrate-agar, {label}: CPU s of its own process", median(runs, "cpu")),
                 (f"calibrate-agar, {label}: CPU s used by other processes", median(runs, "others"))]
    same = found["serial"].keys() == found["2 workers"].keys() and all(
        np.array_equal(found["serial"][k], found["2 workers"][k], equal_nan=True) for k in found["serial"])
    rows += [("speed-up on 2 workers  [bar >= 1.6]", walls["serial"] / walls["2 workers"]),
             ("estimates, errors and intervals identical (1 yes, 0 no)", float(same and bool(found["serial"])))]
    return rows


def combine(directory: Path, cases: int, repeats: int) -> list[tuple[str, float]]:
    from biostudy.data import combine as combining
    from biostudy.data import study_cases, study_fill
    from biostudy.plans.study import load_study

    study = write_study(directory, cases, {**SETTINGS, "time.steps": "2", "time.t_end": "0.002"})
    out = directory / "combine"
    command(directory, "sweep", str(study), "-o", str(out), "--workers", "2")
    plan = load_study(study)
    runs = []
    for _ in range(repeats):
        spent = {"read": 0.0, "fill": 0.0}
        with timed(study_cases.Reader, "read", spent), timed(study_fill, "fill", spent):
            began, cpu = time.perf_counter(), time.process_time()
            combining.write_study(plan, out)
            runs.append((time.perf_counter() - began, time.process_time() - cpu, spent["read"], spent["fill"]))
    wall, cpu, read, fill = sorted(runs)[len(runs) // 2]  # the run of median wall time
    return [("cases", cases), ("study.nc written: wall time (s)", wall),
            ("  case files' attributes, small variables read (s)", read),
            ("  fields copied into study.nc (s)", fill),
            ("  the rest: stacking, small variables written (s)", wall - read - fill),
            ("study.nc written: CPU s", cpu), ("per case (ms)", 1000 * wall / cases),
            ("study.nc (MB)", (out / "study.nc").stat().st_size / 1e6)]


@contextlib.contextmanager
def timed(owner, name: str, spent: dict):
    """Within the block, the wall time spent in `owner.name` is added to spent[name]."""
    original = getattr(owner, name)

    def measured(*args, **kwargs):
        began = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            spent[name] += time.perf_counter() - began

    setattr(owner, name, measured)
    try:
        yield
    finally:
        setattr(owner, name, original)


def table(title: str, rows: list[tuple[str, float]]) -> str:
    width = max(len(title), *(len(r[0]) for r in rows))
    lines = [f"| {title:<{width}} |   value |", f"|{'-' * (width + 2)}|--------:|"]
    lines += [f"| {name:<{width}} | {value:>7.3g} |" for name, value in rows]
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("service", "speedup", "calibration", "combine"), action="append")
    parser.add_argument("--repeats", type=int, default=1, help="runs of each sweep or calibration (the median)")
    parser.add_argument("--cases", type=int, default=1000, help="cases of the combine part")
    parser.add_argument("--steps", type=int, default=100, help="steps of each case of the speedup part (same dt)")
    args = parser.parse_args()
    parts = args.only or ["service", "speedup", "calibration", "combine"]
    os.environ.setdefault("FIPY_SOLVERS", "scipy")
    print(f"load average before: {load_average()} on {os.cpu_count()} cores (anything else running skews the "
          f"figures); python benchmarks/sweep.py {' '.join(sys.argv[1:])}\n")
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        for part in parts:
            title = {"service": "service's own cost (40 x 40, 100 steps, serial)",
                     "speedup": f"36 cases on 2 workers (40 x 40, {args.steps} steps)",
                     "calibration": "calibrate-agar on 2 workers",
                     "combine": f"study.nc of {args.cases} cases"}[part]
            rows = {"service": lambda: service(directory, args.repeats),
                    "speedup": lambda: speedup(directory, args.repeats, args.steps),
                    "calibration": lambda: calibration(directory, args.repeats),
                    "combine": lambda: combine(directory, args.cases, args.repeats)}[part]()
            print(table(title, rows))
            print(f"(load average now: {load_average()})\n", flush=True)
    print(json.dumps({"load_average_after": load_average()}))


if __name__ == "__main__":
    main()
