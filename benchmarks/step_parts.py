"""The small parts of a transport step, timed one by one in this version and another (issue 35.4).

    git archive <commit> | tar -x -C /tmp/old
    python benchmarks/step_parts.py --baseline /tmp/old                  # 40^3, 1 and 2 threads
    python benchmarks/step_parts.py --baseline /tmp/old --size 64 --threads 2

The scene of benchmarks/transport.py (directional, TVD, the front velocity) at n^3 cells, stepped 20 times;
then, on the state it reached, each part is called 200 times and the fastest call kept (the machine is shared:
the fastest is the one least disturbed): the phi matrix with its right-hand side (`Biofilm.assemble`), the
Courant number of the step's velocity (`courant.courant_rate`), one V-cycle of the nutrient's preconditioner,
and two parts issue 35.4 left as they were, for scale and as a control of the noise: the bounds check and
projection of c (`Projection.checked`) and the nutrient's next starting guess (`State.after`, `State.c_guess`).
Each version runs in a fresh process with its own `solver` first on the path, the two in turn, 3 times; the table
has the best of the three and the load average at the start.
Asserts nothing: the figures of docs/transport.md, "Issue 35's look back".
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("assemble", "courant", "vcycle", "checked", "guess")

CHILD = """\
import json, sys, time
sys.path.insert(0, sys.argv[1])
sys.path.insert(1, sys.argv[2])
import numpy as np
from transport import directional
from solver import Simulation
from solver.transport.courant import courant_rate
problem = directional(int(sys.argv[3]), 20, "tvd", "front", 3, int(sys.argv[4]))
run = Simulation(problem)
for snapshot in run:
    pass
transport = run.transport
state = transport.initial()
state = transport.step(transport.step(state, 1e-3), 1e-3)
w, _ = transport.velocity(state)
nutrient = transport.nutrient
matrix = nutrient.matrix(nutrient.gamma * state.phi[nutrient.free])
residual = np.random.default_rng(0).random(matrix.shape[0])

def best(call):
    call()
    times = []
    for _ in range(200):
        began = time.perf_counter()
        call()
        times.append(time.perf_counter() - began)
    return 1e3 * min(times)

print(json.dumps({
    "assemble": best(lambda: transport.biofilm.assemble(state.phi, state.alpha, w, 1e-3)),
    "courant": best(lambda: courant_rate(transport.fv, w)),
    "checked": best(lambda: nutrient._checked(state.c)),
    "guess": best(lambda: state.after(1e-3, state.phi, state.alpha, state.c).c_guess(1e-3)),
    "vcycle": best(lambda: nutrient.amg.cycle(matrix, residual)),
}))
"""


def measure(root: str, n: int, threads: int) -> dict:
    load = os.getloadavg()[0]
    done = subprocess.run([sys.executable, "-c", CHILD, root, str(ROOT / "benchmarks"), str(n), str(threads)],
                          capture_output=True, text=True, cwd=ROOT.parent,
                          env={**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": ""})
    if done.returncode:
        raise SystemExit(f"{root} failed:\n{done.stderr[-2000:]}")
    return {**json.loads(done.stdout.strip().splitlines()[-1]), "load": load}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", required=True, help="another version's directory (its solver/)")
    parser.add_argument("--size", type=int, default=40, help="n of n^3 cells")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    versions = {"this": str(ROOT), "baseline": os.path.abspath(args.baseline)}
    print(f"{args.size}^3, directional, TVD, front velocity; ms per call, the fastest of 200, best of 3 processes")
    print("| version | threads | " + " | ".join(PARTS) + " | load |")
    print("|---|---|" + "---|" * len(PARTS) + "---|")
    for threads in args.threads:
        found: dict[str, list[dict]] = {name: [] for name in versions}
        for _ in range(3):
            for name, root in versions.items():
                found[name].append(measure(root, args.size, threads))
        for name, runs in found.items():
            cells = " | ".join(f"{min(r[part] for r in runs):.3f}" for part in PARTS)
            loads = f"{min(r['load'] for r in runs):.1f}–{max(r['load'] for r in runs):.1f}"
            print(f"| {name} | {threads} | {cells} | {loads} |", flush=True)


if __name__ == "__main__":
    main()
