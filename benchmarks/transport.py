"""Transport cost on the directional scene (paper 4.1), mechanics off: prints a table.

    python benchmarks/transport.py                 # 20^3 and 40^3
    python benchmarks/transport.py --sizes 20 30 40 60 --fipy-default-sizes 20
    python benchmarks/transport.py --advection tvd --growth-velocity front pointwise --fipy-default-sizes

Per grid: ms per step split into nutrient solve, velocity, phi solve and
bookkeeping (everything else in the loop: expansion, checks, snapshots), the
one-off setup, peak memory (each size runs in a fresh process), and the same
grid stepped by plain FiPy (`tests/fipy_reference.py`, every matrix rebuilt)
with its default solvers (LU) and with CG/GMRES (the pointwise growth velocity,
as FiPy's terms write it).  Each growth velocity asked for gets its own rows.
The cost exponent is fitted between the smallest and largest size: time per
step ~ N^p.
Asserts nothing: a table for docs/transport.md.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def directional(n: int, steps: int, advection: str = "upwind", velocity: str = "pointwise"):
    from solver import Grid, Numerics, Problem

    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    phi0 = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    held = (x > 17) & (y > 17) & (z > 17)
    dt = 1e-3
    return Problem(grid=grid, phi0=phi0, nutrient_held=held, t_end=steps * dt, steps=steps,
                   output_times=[0.0, steps * dt], numerics=Numerics(advection=advection, growth_velocity=velocity),
                   name="directional")


def measure_fast(n: int, steps: int, advection: str, velocity: str) -> dict:
    from solver import Simulation

    began = time.perf_counter()
    run = Simulation(directional(n, steps, advection, velocity))
    snapshots = iter(run)
    next(snapshots)  # t = 0: operators built, first nutrient solve, first AMG hierarchy
    setup = time.perf_counter() - began
    before = dict(run.transport.timings)
    loop_start = time.perf_counter()
    for _ in snapshots:
        pass
    loop = time.perf_counter() - loop_start
    report = run.report()
    stages = {k: report["timings"].get(k, 0.0) - before.get(k, 0.0) for k in ("nutrient", "velocity", "biofilm")}
    per_step = {k: 1e3 * v / steps for k, v in stages.items()}
    per_step["bookkeeping"] = 1e3 * loop / steps - sum(per_step.values())
    per_step["total"] = 1e3 * loop / steps
    return {"setup_s": setup, "per_step_ms": per_step, "cg_iterations": report["nutrient_cg_iterations"] / (steps + 1),
            "amg_rebuilds": report["nutrient_amg_rebuilds"]}


def measure_fipy(n: int, steps: int, solvers: str) -> dict:
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "tests"))
    from fipy_reference import FipyTransport  # the plain-FiPy reference lives beside the tests that use it

    reference = FipyTransport(directional(n, steps), solvers=solvers)
    reference.solve_nutrient()
    start = time.perf_counter()
    for _ in range(steps):
        reference.step(1e-3)
    return {"per_step_ms": 1e3 * (time.perf_counter() - start) / steps}


def one(args) -> None:
    """Child process: one measurement, printed as JSON with the peak memory."""
    kind, n, steps = args.one, args.n, args.steps
    if kind == "fast":
        result = measure_fast(n, steps, args.advection, args.velocity)
    else:
        result = measure_fipy(n, steps, kind)
    result["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(result))


def child(kind: str, n: int, steps: int, advection: str = "upwind", velocity: str = "pointwise") -> dict:
    command = [sys.executable, __file__, "--one", kind, "--n", str(n), "--steps", str(steps), "--advection", advection,
               "--velocity", velocity]
    out = subprocess.run(command, check=True, capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40])
    parser.add_argument("--steps", type=int, default=100, help="steps timed at the smallest size (fewer above)")
    parser.add_argument("--fipy-default-sizes", type=int, nargs="*", default=[20],
                        help="sizes also run with FiPy's default (LU) solvers; 40^3 costs ~30 s per step")
    parser.add_argument("--fipy-steps", type=int, default=5)
    parser.add_argument("--advection", default="upwind", choices=["upwind", "tvd"])
    parser.add_argument("--growth-velocity", nargs="+", default=["front", "pointwise"], choices=["front", "pointwise"])
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--velocity", default="pointwise", help=argparse.SUPPRESS)
    parser.add_argument("--n", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        return one(args)

    rows = []
    for n in args.sizes:
        steps = max(20, int(args.steps * (args.sizes[0] / n) ** 3))
        iterative = child("iterative", n, args.fipy_steps)
        default = child("default", n, args.fipy_steps) if n in args.fipy_default_sizes else None
        for velocity in args.growth_velocity:
            rows.append((n, velocity, steps, child("fast", n, steps, args.advection, velocity), iterative, default))

    print(f"directional scene, mechanics off, dt = 1e-3, advection = {args.advection}, "
          f"FIPY_SOLVERS = {os.environ['FIPY_SOLVERS']}, OMP_NUM_THREADS = {os.environ['OMP_NUM_THREADS']}")
    print("| cells | growth velocity | steps | nutrient | velocity | phi solve | bookkeeping | **total ms/step** "
          "| CG its/solve | AMG builds | setup s | peak MB | FiPy CG/GMRES ms/step | FiPy default (LU) ms/step "
          "| speed-up vs LU |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n, velocity, steps, fast, iterative, default in rows:
        s = fast["per_step_ms"]
        lu = f"{default['per_step_ms']:.0f}" if default else "not run"
        speedup = f"{default['per_step_ms'] / s['total']:.0f}x" if default else "-"
        print(f"| {n}^3 | {velocity} | {steps} | {s['nutrient']:.1f} | {s['velocity']:.1f} | {s['biofilm']:.1f} | "
              f"{s['bookkeeping']:.1f} | **{s['total']:.1f}** | {fast['cg_iterations']:.1f} | {fast['amg_rebuilds']} | "
              f"{fast['setup_s']:.2f} | {fast['peak_mb']:.0f} | {iterative['per_step_ms']:.0f} | {lu} | {speedup} |")
    for velocity in args.growth_velocity:
        mine = [r for r in rows if r[1] == velocity]
        if len(mine) > 1:
            (n0, *_, f0, _, _), (n1, *_, f1, _, _) = mine[0], mine[-1]
            exponent = np.log(f1["per_step_ms"]["total"] / f0["per_step_ms"]["total"]) / np.log((n1 / n0) ** 3)
            print(f"\n{velocity}: cost per step grows as N^{exponent:.2f} in the cell count N "
                  f"between {n0}^3 and {n1}^3")


if __name__ == "__main__":
    main()
