"""Set-up before the first step (issue 35.3): wall time and peak memory per cell, two grids differenced.

    python benchmarks/setup.py                                # 40^3 and 80^3, 2 steps, mechanics off
    python benchmarks/setup.py --baseline /tmp/old            # and another version's tree, case by case beside
    python benchmarks/setup.py --sizes 40 80 --repeats 3      # medians of 3

The scene: `studies/directional.toml` (paper 4.1) at n^3 cells of 20/n µm, 2 steps, mechanics off.  Each case is
a fresh process that loads the scene, compiles its problem and runs `solver.Simulation`; "before the first step"
is everything up to the output at t = 0 (the interpreter's start and imports, the scene, the transport's
operators, the first nutrient solve with its multigrid hierarchy), measured as the wall time from the process's
first line (and the process's CPU time: on a busy machine closer to what an idle one takes) and its peak
resident memory (VmHWM) then, with what it holds then (VmRSS).  The difference between the two sizes, divided by the
difference of their cell counts, is the cost per cell: the fixed start (interpreter, imports) cancels.  The
whole run's wall time and peak are beside.  Asserts nothing: tables for docs/transport.md.
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
import time
began = time.perf_counter()
cpu = time.process_time()
import json, re, sys
from biostudy.execution.worker import pin_solvers
pin_solvers()
from biostudy.inputs.scene import load_scene
from solver import Simulation


def status(field):
    return int(re.search(field + r":\\s+(\\d+) kB", open("/proc/self/status").read()).group(1)) * 1024


run = Simulation(load_scene(sys.argv[1], sys.argv[2:]).problem())
snapshots = iter(run)
next(snapshots)
first, first_cpu, first_peak, first_held = (time.perf_counter() - began, time.process_time() - cpu,
                                            status("VmHWM"), status("VmRSS"))
for _ in snapshots:
    pass
print(json.dumps({"first": first, "first_cpu": first_cpu, "first_peak": first_peak, "first_held": first_held,
                  "whole": time.perf_counter() - began, "peak": status("VmHWM")}))
"""


def case(n: int, steps: int, tree: Path) -> dict:
    """One run in a fresh process, with `tree`'s biostudy and solver."""
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-c", CHILD, str(SCENE), f"grid.shape=[{n},{n},{n}]",
                           f"grid.spacing={20.0 / n!r}", f"time.steps={steps}", f"time.t_end={steps * 1e-3!r}",
                           "time.outputs=2", "mechanics.enabled=false"],
                          capture_output=True, text=True, cwd=ROOT.parent,
                          env={**os.environ, "PYTHONPATH": str(tree), "BIOSTUDY_MEMORY": "1 TB"})
    if done.returncode:
        raise SystemExit(f"{n}^3 ({tree}) failed:\n{done.stderr[-2000:]}")
    return {**json.loads(done.stdout.strip().splitlines()[-1]), "load": load}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs=2, default=[40, 80], help="two n of n^3 cells")
    parser.add_argument("--steps", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1, help="runs of each case, in turn; the table has medians")
    parser.add_argument("--baseline", help="another version's tree (e.g. git archive main | tar -x -C /tmp/old)")
    args = parser.parse_args()
    trees = [("this", ROOT)] + ([("baseline", Path(args.baseline).resolve())] if args.baseline else [])
    runs: dict[tuple[str, int], list[dict]] = {(label, n): [] for label, _ in trees for n in args.sizes}
    for _ in range(args.repeats):
        for n in args.sizes:
            for label, tree in trees:
                runs[label, n].append(case(n, args.steps, tree))
                print(f"# {label} {n}^3: {runs[label, n][-1]['first']:.2f} s to the first step "
                      f"(load {runs[label, n][-1]['load']:.1f})", file=sys.stderr, flush=True)

    def median(label, n, key):
        return statistics.median(r[key] for r in runs[label, n])

    small, large = args.sizes
    cells = large**3 - small**3
    print(f"directional scene, mechanics off, {args.steps} steps; medians of {args.repeats}")
    print("| version | cells | to the first step s (CPU) | peak then GB | held then GB | whole run s | whole peak GB "
          "| load |")
    print("|---|---|---|---|---|---|---|---|")
    for label, _ in trees:
        for n in args.sizes:
            loads = [r["load"] for r in runs[label, n]]
            print(f"| {label} | {n}^3 | {median(label, n, 'first'):.2f} ({median(label, n, 'first_cpu'):.2f}) "
                  f"| {median(label, n, 'first_peak') / 1e9:.2f} | {median(label, n, 'first_held') / 1e9:.2f} "
                  f"| {median(label, n, 'whole'):.2f} | {median(label, n, 'peak') / 1e9:.2f} "
                  f"| {min(loads):.1f}–{max(loads):.1f} |")
    print(f"\nbefore the first step, {large}^3 against {small}^3, per cell:")
    print("| version | **µs** (CPU µs) | **kB at the peak** | kB held |")
    print("|---|---|---|---|")
    for label, _ in trees:
        per = {key: (median(label, large, key) - median(label, small, key)) / cells
               for key in ("first", "first_cpu", "first_peak", "first_held")}
        print(f"| {label} | **{1e6 * per['first']:.1f}** ({1e6 * per['first_cpu']:.1f}) "
              f"| **{per['first_peak'] / 1e3:.2f}** | {per['first_held'] / 1e3:.2f} |")


if __name__ == "__main__":
    main()
