"""One run on several threads (issue 35.2): the time loop's wall time by thread count, and the fields it ends with.

    python benchmarks/threads.py                                   # 64^3 without mechanics, 30 steps, 1 .. cores
    python benchmarks/threads.py --repeats 5                       # each count 5 times, in turn: medians
    python benchmarks/threads.py --sizes 32 48 --steps 4 --mechanics   # the mechanics' solves (docs/mechanics.md)
    python benchmarks/threads.py --handoff --baseline /tmp/old      # a team's hand-over of an empty part, µs

The scene: `studies/directional.toml` (paper 4.1) at n^3 cells of 20/n µm, its time step (dt = 1e-3), `--steps`
steps, two outputs (the start and the end), mechanics off unless `--mechanics` (then solved at both outputs), the
thread count set as a scene does (``[numerics] threads``).  Each case is a fresh process that runs the solver's
time loop (`solver.Simulation`); the counts run in turn (1, 2, ..., 1, 2, ...) so that a machine whose load
drifts disturbs them alike.  Per case: the time loop's wall time (every step after the output at t = 0, the
mechanics solve at the end included), its parts per step, the mechanics' seconds per solve, the CPU seconds of
the run's threads, and a digest of the fields at the end (phi, c, alpha; u and p with the mechanics): the same
digest for every count is the same fields bit for bit.  The table gives the median of the repeats, the loop's
time against one thread's and the load average at each case's start (the machine may be shared).
`--handoff`: how long a team of two threads takes to hand an empty part to its helper and hear it done (what
every parallel call pays on top of its work), and a vector update of the size of a 40^3 run's (x += a p, the
half of 64 000 entries each) on two threads and on one, the best of 5 batches of 2000 calls, in a fresh process
each for this version and, with --baseline DIR, for DIR's `solver` (`git archive <commit> | tar -x -C DIR`), in
turn 3 times.
Asserts nothing: tables for docs/transport.md and docs/mechanics.md.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "studies" / "directional.toml"

CHILD = """\
import hashlib, json, sys, time
from biostudy.execution.worker import pin_solvers
pin_solvers()
import numpy as np
from biostudy.inputs.scene import load_scene
from solver import Simulation
problem = load_scene(sys.argv[1], sys.argv[2:]).problem()
run = Simulation(problem)
snapshots = iter(run)
first = next(snapshots)  # t = 0: operators, the first nutrient solve (and mechanics solve)
before, mechanics_before = dict(run.transport.timings), run.transport.timings.get("mechanics", 0.0)
began, cpu = time.perf_counter(), run.report()["cpu_time_loop"]
last = [s for s in snapshots][-1]
loop = time.perf_counter() - began
report = run.report()
digest = hashlib.sha256()
for name in ("phi", "c", "alpha", "u", "p"):
    value = getattr(last, name, None)
    if value is not None:
        digest.update(np.ascontiguousarray(value).tobytes())
parts = {k: report["timings"].get(k, 0.0) - before.get(k, 0.0)
         for k in ("nutrient", "velocity", "biofilm", "mechanics")}
print(json.dumps({"loop": loop, "parts": parts, "cpu": report["cpu_time_loop"] - cpu, "threads": report["threads"],
                  "steps": report["steps_taken"], "digest": digest.hexdigest()[:16],
                  "solves": int(first.u is not None) + int(last.u is not None)}))
"""


HANDOFF = """\
import json, time
import numpy as np
from solver.parallel import Team
from solver.parallel.vectors import add_scaled
x, p = np.zeros(64000), np.ones(64000)
def best(team, work):
    for _ in range(200):
        work(team)
    found = float("inf")
    for _ in range(5):
        began = time.perf_counter()
        for _ in range(2000):
            work(team)
        found = min(found, (time.perf_counter() - began) / 2000)
    return 1e6 * found
empty = lambda team: team.run(lambda part: None, together=True)
update = lambda team: add_scaled(team, x, 0.5, p)
two = Team(2)
print(json.dumps({"empty": best(two, empty), "update": best(two, update), "serial": best(Team(1), update)}))
"""


def handoff(baseline: str | None) -> None:
    """The hand-over table (module docstring)."""
    versions = [("this", str(ROOT))] + ([("baseline", os.path.abspath(baseline))] if baseline else [])
    print("| version | empty part on 2 threads, µs | x += a p (64 000 entries) on 2 threads, µs | on 1 thread, µs "
          "| load |")
    print("|---|---|---|---|---|")
    for _ in range(3):
        for name, path in versions:
            load = os.getloadavg()[0]
            done = subprocess.run([sys.executable, "-c", HANDOFF], capture_output=True, text=True, check=True,
                                  cwd=ROOT.parent, env={**os.environ, "PYTHONPATH": path})
            found = json.loads(done.stdout)
            print(f"| {name} | {found['empty']:.1f} | {found['update']:.1f} | {found['serial']:.1f} | {load:.1f} |",
                  flush=True)


def overrides(n: int, steps: int, mechanics: bool, threads: int) -> list[str]:
    return [f"grid.shape=[{n},{n},{n}]", f"grid.spacing={20.0 / n!r}", f"time.steps={steps}",
            f"time.t_end={steps * 1e-3!r}", "time.outputs=2", f"mechanics.enabled={str(mechanics).lower()}",
            "mechanics.every=1", f"numerics.threads={threads}"]


def case(n: int, steps: int, mechanics: bool, threads: int) -> dict:
    """One run in a fresh process."""
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-c", CHILD, str(SCENE), *overrides(n, steps, mechanics, threads)],
                          capture_output=True, text=True, cwd=ROOT.parent,
                          env={**os.environ, "PYTHONPATH": str(ROOT), "BIOSTUDY_MEMORY": "1 TB"})
    if done.returncode:
        raise SystemExit(f"{n}^3 on {threads} threads failed:\n{done.stderr[-2000:]}")
    return {**json.loads(done.stdout.strip().splitlines()[-1]), "load": load}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[64], help="n of n^3 cells")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--threads", type=int, nargs="+", help="thread counts (default: 1 up to the processors here)")
    parser.add_argument("--repeats", type=int, default=1, help="runs of each count, in turn; the table has medians")
    parser.add_argument("--mechanics", action="store_true", help="with the mechanics, solved at both outputs")
    parser.add_argument("--handoff", action="store_true", help="time a team's hand-over of an empty part instead")
    parser.add_argument("--baseline", help="with --handoff: another version's directory, timed in turn")
    args = parser.parse_args()
    if args.handoff:
        handoff(args.baseline)
        return
    counts = args.threads or list(range(1, len(os.sched_getaffinity(0)) + 1))

    print(f"directional scene, {args.steps} steps, mechanics {'on' if args.mechanics else 'off'}; "
          f"{len(os.sched_getaffinity(0))} processors here; medians of {args.repeats}")
    print("| cells | threads | loop s | ms/step: nutrient / velocity / phi solve | mechanics s/solve "
          "| **loop / 1 thread** | CPU s | fields (digest) | same as 1 thread | load |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        runs: dict[int, list[dict]] = {t: [] for t in counts}
        for _ in range(args.repeats):
            for threads in counts:
                runs[threads].append(case(n, args.steps, args.mechanics, threads))
                print(f"# {n}^3, {threads} threads: {runs[threads][-1]['loop']:.2f} s "
                      f"(load {runs[threads][-1]['load']:.1f})", file=sys.stderr, flush=True)
        one = statistics.median(r["loop"] for r in runs[counts[0]])
        for threads in counts:
            rs = runs[threads]
            loop = statistics.median(r["loop"] for r in rs)
            steps = rs[0]["steps"]
            parts = [statistics.median(r["parts"][k] for r in rs) * 1e3 / steps for k in ("nutrient", "velocity",
                                                                                          "biofilm")]
            solves = rs[0]["solves"]
            mechanics = (f"{statistics.median(r['parts']['mechanics'] for r in rs) / max(solves - 1, 1):.2f}"
                         if solves else "–")
            digests = {r["digest"] for r in rs}
            same = digests == {r["digest"] for r in runs[counts[0]]}
            loads = f"{min(r['load'] for r in rs):.1f}–{max(r['load'] for r in rs):.1f}"
            print(f"| {n}^3 | {threads} | {loop:.2f} | {parts[0]:.0f} / {parts[1]:.0f} / {parts[2]:.0f} | {mechanics} "
                  f"| **{loop / one:.2f}** | {statistics.median(r['cpu'] for r in rs):.1f} | {', '.join(digests)} "
                  f"| {'yes' if same else '**no**'} | {loads} |")


if __name__ == "__main__":
    main()
