"""What a sweep costs beyond its simulations, and how it scales on local processes: prints tables.

    python benchmarks/sweep.py                      # defaults below, ~1 min on 2 quiet cores
    python benchmarks/sweep.py --only speedup --steps 1600

1. Overhead per case: a serial sweep of small directional cases (12³, 21
   outputs); its wall time minus the simulations' own wall time (the
   solver's `wall_time` attribute), split into validating the study,
   compiling and fingerprinting each case, writing each case file (stamp,
   netCDF, fsync, rename) and combining study.nc.  Target: <= 0.5 s per case.
2. Speed-up: a 4-case sweep of the bundled 2-D directional scene at 48²
   (1600 steps, no mechanics: a few seconds per case on a quiet core)
   serially in this process and on 2 local worker processes
   (`--workers 2`, process start-up included), then the same as commands
   (`biostudy sweep`, serial and `--workers 2`: what a user waits for, the
   process's own start included).  Target: >= 1.8x on 2 cores.
   "simulation per case" shows what two simulations at once cost each other
   (shared memory bandwidth), apart from the start-up of the workers; "pool
   start-up" is the time from a cold start of the fork server to two workers
   answering; "other processes" counts CPU seconds the rest of the machine
   took meanwhile (on a shared machine a speed-up measured while they ran is
   not the sweep's own).

Asserts nothing.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("FIPY_SOLVERS", "scipy")  # before FiPy is first imported

import psutil  # noqa: E402
import xarray as xr  # noqa: E402

from biostudy.commands.sweep import run_study  # noqa: E402
from biostudy.data import case_files, combine, reading, writing  # noqa: E402
from biostudy.execution.jobs import Execution, fingerprint  # noqa: E402
from biostudy.inputs import bundled  # noqa: E402
from biostudy.plans.study import load_study  # noqa: E402


def sweep(plan, out, **execution):
    """A study's sweep into `out` as `biostudy sweep` runs it (`execution`: workers, retry_failed, ...)."""
    return run_study(plan, out, Execution(**execution))


def write_study(directory: Path, name: str, scene_overrides: dict, values: list[float],
                scene: str = "directional") -> Path:
    """A study of a bundled scene sweeping r, with fixed overrides (mechanics off, upwind)."""
    shutil.copy(bundled.resolve(scene), directory / f"{scene}.toml")
    fixed = "\n".join(f'"{k}" = {v}' for k, v in scene_overrides.items())
    path = directory / f"{name}.toml"
    path.write_text(f'scene = "{scene}.toml"\n[set]\n"mechanics.enabled" = false\n"numerics.advection" = "upwind"\n'
                    f'{fixed}\n[sweep]\nr = {values}\n')
    return path


class Others:
    """CPU seconds that processes other than this one and its children used during a block: on a
    shared machine, a speed-up measured while they ran is not the sweep's own."""

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
        for process in psutil.Process().children(recursive=True):  # e.g. the fork server and its workers
            try:
                t = process.cpu_times()
                own += t.user + t.system + t.children_user + t.children_system
            except psutil.NoSuchProcess:
                pass
        return system - own


def simulated_seconds(out: Path) -> float:
    total = 0.0
    for path in (out / "cases").glob("*.nc"):
        with xr.open_dataset(path) as ds:
            total += float(ds.attrs["wall_time"])
    return total


def overhead(directory: Path, cases: int) -> list[tuple[str, float]]:
    values = [50.0 + 10 * i for i in range(cases)]
    study = write_study(directory, "overhead", {"grid.shape": "[12, 12, 12]", "grid.spacing": 20 / 12,
                                                "time.steps": 100, "time.outputs": 21,
                                                "nutrient.0.lower": "[16.0, 16.0, 16.0]"}, values)
    began = time.perf_counter()
    plan = load_study(study)
    validate = time.perf_counter() - began
    out = directory / "overhead-out"
    began = time.perf_counter()
    sweep(plan, out)
    total = time.perf_counter() - began + validate
    simulated = simulated_seconds(out)

    # the parts, timed again one by one on the finished cases
    began = time.perf_counter()
    for case in plan.cases:
        fingerprint(plan.scenes[case.id].problem())
    compile_ = time.perf_counter() - began
    began = time.perf_counter()
    for case in plan.cases:
        path = case_files.case_file(out, case.id)
        ds = reading.open_dataset(path)
        writing.write_atomic(ds, path)
    write = time.perf_counter() - began
    began = time.perf_counter()
    combine.write_study(plan, out)
    combined = time.perf_counter() - began
    n = len(plan.cases)
    return [("cases", n), ("sweep wall time (s)", total), ("simulations' own wall time (s)", simulated),
            ("overhead per case (s)", (total - simulated) / n),
            ("  validate the study, per case (s)", validate / n),
            ("  compile + fingerprint, per case (s)", compile_ / n),
            ("  write one case file, per case (s)", write / n),
            ("  combine study.nc, per case (s)", combined / n)]


POOL_START = """
import os, time
os.environ["FIPY_SOLVERS"] = "scipy"
from biostudy.execution import pool as local
if __name__ == "__main__":
    began = time.perf_counter()
    pool = local.LocalPool(2)
    pool.submit("a", None)  # solve(None) fails at once in the worker: a round trip
    pool.submit("b", None)
    while pool.busy:
        pool.finished()
    print(time.perf_counter() - began)
    pool.close(True)
"""


def pool_start(directory: Path) -> float:
    """Seconds from nothing to two local workers answering (fork server cold start with its imports, two forks),
    in a fresh process."""
    script = directory / "pool_start.py"
    script.write_text(POOL_START)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, check=True)
    return float(done.stdout.strip())


def speedup(directory: Path, steps: int) -> list[tuple[str, float]]:
    study = write_study(directory, "speedup", {"grid.shape": "[48, 48]", "grid.spacing": 20 / 48, "time.steps": steps,
                                               "time.outputs": 11}, [50.0, 80.0, 120.0, 160.0], "directional2d")
    plan = load_study(study)
    rows = [("pool start-up (s)", pool_start(directory))]
    times = {}
    for label, workers in (("serial", None), ("2 local workers", 2)):
        out = directory / f"speedup-{workers}"
        began, cpu = time.perf_counter(), time.process_time()
        with Others() as others:
            sweep(plan, out, workers=workers)
        times[label] = time.perf_counter() - began
        rows.append((f"{label}: sweep wall time (s)", times[label]))
        rows.append((f"{label}: simulation per case (s)", simulated_seconds(out) / len(plan.cases)))
        rows.append((f"{label}: CPU s of this process (with workers: writing, combining)",
                     time.process_time() - cpu))
        rows.append((f"{label}: CPU s used by other processes", others.seconds))
    rows.append(("speed-up", times["serial"] / times["2 local workers"]))
    for label, workers in (("serial", []), ("2 local workers", ["--workers", "2"])):  # as a user runs it
        began = time.perf_counter()
        with Others() as others:
            subprocess.run([sys.executable, "-m", "biostudy", "sweep", str(study), "-o",
                            str(directory / f"command-{len(workers)}"), "-q", *workers], check=True,
                           stderr=subprocess.DEVNULL)
        times[label] = time.perf_counter() - began
        rows.append((f"`biostudy sweep`, {label}: wall time (s)", times[label]))
        rows.append((f"`biostudy sweep`, {label}: CPU s used by other processes", others.seconds))
    rows.append(("`biostudy sweep`: speed-up", times["serial"] / times["2 local workers"]))
    return rows


def table(title: str, rows: list[tuple[str, float]]) -> str:
    width = max(len(title), *(len(r[0]) for r in rows))
    lines = [f"| {title:<{width}} |   value |", f"|{'-' * (width + 2)}|--------:|"]
    lines += [f"| {name:<{width}} | {value:>7.3g} |" for name, value in rows]
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=8, help="cases of the overhead sweep")
    parser.add_argument("--steps", type=int, default=1600, help="steps per case of the speed-up sweep (2-D 48²)")
    parser.add_argument("--only", choices=("overhead", "speedup"), help="one of the two tables")
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores "
          "(anything else running skews the speed-up)\n")
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        if args.only != "speedup":
            print(table("overhead (12³, 100 steps, 21 outputs, serial)", overhead(directory, args.cases)))
            print()
        if args.only != "overhead":
            print(table(f"speed-up (2-D 48², {args.steps} steps, 4 cases)", speedup(directory, args.steps)))
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
