"""Interrupts sent at random moments to `biostudy calibrate`: is every one obeyed, and is a finished simulation kept?

Each trial starts the tiny agar twin's calibration (12 x 16 cells, 40 steps; g and r from one start, no
profiles: ~50 simulations, ~10-20 s) in a process of its own, sends SIGINT or SIGTERM (alternately) at a moment
drawn uniformly from [0.5 s, the calibration's own length], and records

- the exit status (130 for SIGINT, 143 for SIGTERM; -2, -15 when the signal came as the process exited, its
  command done: the signal's default action, which a shell also reports as 130, 143) and how long the process
  took to end after the signal (a process still running 20 s later is killed and counted as "kept running");
- "Exception ignored" on stderr: an interrupt raised inside a finaliser (FiPy's `Solver.__del__`) or another
  place Python cannot propagate it from, which on 0.4.0 was swallowed;
- simulations finished but not recorded: the process logs every simulation that returned (a wrapper around
  `execution.backends.Here.finished`, in the process itself); one without its case file under DIR/cases/ after
  the process ended was lost, and the next run would compute it again.

Then the calibration is resumed to its end (`--set` nothing, the same directory) once every few trials, as a
check that what was kept is reused.  Prints one row per trial and a summary; asserts nothing.

    python benchmarks/interrupts.py [--trials 60] [--seed 0]
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from test_calibration import CALIBRATION as PROFILED  # noqa: E402  (the tests' tiny 2-D twin)
from test_calibration import SCENE  # noqa: E402

CALIBRATION = PROFILED.replace("starts = 2", "starts = 1").replace("profiles = true", "profiles = false")
# the calibration, each simulation that returned logged to FINISHED (one case id a line) before it is recorded
WRAPPER = textwrap.dedent("""\
    import os, sys
    os.environ.setdefault("FIPY_SOLVERS", "scipy")
    from biostudy.execution import backends

    finished = backends.Here.finished
    log = open(os.environ["FINISHED"], "a", buffering=1)

    def logged(self):
        done = finished(self)
        for case_id, _ in done:
            log.write(case_id + "\\n")
        return done

    backends.Here.finished = logged
    from biostudy.cli import app
    sys.argv = ["biostudy", *sys.argv[1:]]
    app()
    """)
PATIENCE = 20.0  # seconds a process may take to end after its signal


def load_average() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def prepare(folder: Path) -> None:
    from biostudy.commands import twin

    (folder / "agar.toml").write_text(SCENE)
    (folder / "twin.tsv").write_text(twin.table(folder / "agar.toml", truth={"g": 1e9, "r": 100.0},
                                                observables_measured=["biomass", "max_thickness"],
                                                times=[1.0, 2.0, 3.0, 4.0], time_factor=1 / 20, noise=0.05,
                                                seed=1001))
    (folder / "cal.toml").write_text(CALIBRATION)
    (folder / "wrapper.py").write_text(WRAPPER)


def calibrate(folder: Path, out: Path, log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(folder / "wrapper.py"), "calibrate", str(folder / "cal.toml"),
                             "-o", str(out), "-q"], cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "FINISHED": str(log)})


def trial(folder: Path, number: int, length: float, rng: random.Random) -> dict:
    out, log = folder / f"out{number}", folder / f"finished{number}.txt"
    sent = (signal.SIGINT, signal.SIGTERM)[number % 2]
    at = rng.uniform(0.5, length)
    process = calibrate(folder, out, log)
    time.sleep(at)
    ended_before = process.poll() is not None
    process.send_signal(sent)
    began = time.monotonic()
    try:
        _, stderr = process.communicate(timeout=PATIENCE)
        took, running = time.monotonic() - began, False
    except subprocess.TimeoutExpired:
        process.kill()
        _, stderr = process.communicate()
        took, running = PATIENCE, True
    finished = set(log.read_text().split()) if log.exists() else set()
    recorded = {p.stem for p in (out / "cases").glob("*.nc")} if (out / "cases").exists() else set()
    return {"trial": number, "signal": sent.name, "at": at, "status": process.returncode, "took": took,
            "expected": 128 + sent, "running": running, "ignored": stderr.count("Exception ignored"),
            "lost": sorted(finished - recorded), "finished": len(finished), "ended_before": ended_before,
            "stderr": stderr.strip().splitlines()[-1:] if stderr.strip() else []}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=60, help="signals that reach a running calibration")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch)
        prepare(folder)
        began = time.monotonic()
        whole = calibrate(folder, folder / "whole", folder / "whole.txt")
        whole.communicate()
        length = time.monotonic() - began
        print(f"load average {load_average()}; one uninterrupted calibration {length:.1f} s "
              f"(exit {whole.returncode}); {args.trials} trials\n")
        print("| trial | signal | at (s) | exit | ended after (s) | Exception ignored | finished, not recorded |")
        print("|---|---|---|---|---|---|---|")
        rows = []
        for number in range(3 * args.trials):  # until `trials` signals reached a running calibration
            if sum(not r["ended_before"] for r in rows) == args.trials:
                break
            row = trial(folder, number, length, rng)
            rows.append(row)
            if row["ended_before"]:  # the load fell: it ran faster than the first
                continue
            wrong = row["status"] not in (row["expected"], -row["expected"] + 128) or row["running"] \
                or row["ignored"] or row["lost"]
            print(f"| {number} | {row['signal']} | {row['at']:.2f} | {row['status']}"
                  f"{' (kept running)' if row['running'] else ''} | {row['took']:.2f} | {row['ignored']} | "
                  f"{', '.join(row['lost']) or '-'} |{'  <--' if wrong else ''}")
        counted = [r for r in rows if not r["ended_before"]]
        print(f"\n{len(counted)} interrupts sent to a running calibration: "
              f"{sum(r['status'] == r['expected'] for r in counted)} ended with 130/143, "
              f"{sum(r['status'] == 128 - r['expected'] for r in counted)} by the signal itself (-2/-15: it came as "
              "the process exited, its command done, after its handlers were put back; a shell says 130/143), "
              f"{sum(r['running'] for r in counted)} kept running {PATIENCE:g} s, "
              f"{sum(bool(r['ignored']) for r in counted)} with 'Exception ignored', "
              f"{sum(len(r['lost']) for r in counted)} finished simulations not recorded; "
              f"slowest exit {max((r['took'] for r in counted), default=0):.2f} s")
        print(f"load average {load_average()}")


if __name__ == "__main__":
    main()
