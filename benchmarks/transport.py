"""Transport cost on the directional scene (paper 4.1), mechanics off: prints tables.

    python benchmarks/transport.py                                   # 20^3 and 40^3, TVD, front and pointwise
    python benchmarks/transport.py --baseline /tmp/old               # the same for another version, side by side
    python benchmarks/transport.py --sizes 20 30 40 60 80 --sizes-2d 80 160 320 640 --growth-velocity front
    python benchmarks/transport.py --advection upwind --fipy-default-sizes 20 30

The scene: a 20 µm cube (square in 2-D) in n^3 (n^2) cells, phi = 1 in a
sphere (disc) of radius 5 µm at the centre, c = 1 held in the corner region
x, y (, z) > 17 µm, Table 2 parameters, dt = 1e-3; TVD advection unless
--advection says otherwise (the bundled paper scenes use TVD).  Each case
runs in a fresh process: the operators are built and the first step taken
(compiled kernels loaded) before the clock starts, then `--steps` steps at the
smallest size (fewer above, at least --min-steps) are timed.  Per case: ms per
step split into nutrient solve, velocity (growth velocity, with the front
extension), phi solve and bookkeeping (everything else in the loop:
expansion, checks, snapshots), CG iterations per nutrient solve, BiCGSTAB
iterations per phi solve, the one-off setup, the peak memory and the load
average when the case started (the machine is shared), and the loop's CPU
time per step: one thread, so equal to the wall time on a quiet machine and
less disturbed by other jobs on a busy one.

--baseline DIR runs every case also with DIR's `solver` first on the path (for
instance the commit before issue 20: `git archive 60716c6 | tar -x -C /tmp/old`)
and prints the ratio baseline / this of the total per step (wall and CPU), pair
by pair: the two versions run one after the other at each size.  The same grid stepped by
plain FiPy (`tests/fipy_reference.py`, every matrix rebuilt; the pointwise
growth velocity, as FiPy's terms write it) with CG/GMRES and with FiPy's
default solver (LU) is run at --fipy-sizes and --fipy-default-sizes.  The cost
exponent is fitted between the smallest and largest size: time per step ~ N^p.
Asserts nothing: tables for docs/transport.md.
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

DT = 1e-3


def directional(n: int, steps: int, advection: str = "tvd", velocity: str = "pointwise", ndim: int = 3,
                threads: int | None = None):
    """The benchmark's scene on n^ndim cells; outputs after the first step and at the end; `threads`: the run's
    (a version before threads has none)."""
    from solver import Grid, Numerics, Problem

    grid = Grid((n,) * ndim, 20.0 / n)
    coordinates = grid.cell_coordinates()
    phi0 = (sum((q - 10) ** 2 for q in coordinates) <= 25).astype(float)
    held = np.logical_and.reduce([q > 17 for q in coordinates])
    return Problem(grid=grid, phi0=phi0, nutrient_held=held, t_end=(steps + 1) * DT, steps=steps + 1,
                   output_times=[0.0, DT, (steps + 1) * DT],
                   numerics=Numerics(advection=advection, growth_velocity=velocity,
                                     **({"threads": threads} if threads else {})), name="directional")


def measure_fast(n: int, steps: int, advection: str, velocity: str, ndim: int, threads: int | None) -> dict:
    from solver import Simulation

    problem = directional(n, steps, advection, velocity, ndim, threads)
    began = time.perf_counter()
    run = Simulation(problem)
    snapshots = iter(run)
    next(snapshots)  # t = 0: operators built, first nutrient solve, first AMG hierarchy
    next(snapshots)  # one step: compiled kernels loaded
    setup = time.perf_counter() - began
    before = dict(run.transport.timings)
    counts = run.report()
    loop_start, cpu_start = time.perf_counter(), time.process_time()
    for _ in snapshots:
        pass
    loop, cpu = time.perf_counter() - loop_start, time.process_time() - cpu_start
    report = run.report()
    stages = {k: report["timings"].get(k, 0.0) - before.get(k, 0.0) for k in ("nutrient", "velocity", "biofilm")}
    per_step = {k: 1e3 * v / steps for k, v in stages.items()}
    per_step["bookkeeping"] = 1e3 * loop / steps - sum(per_step.values())
    per_step["total"] = 1e3 * loop / steps
    per_step["cpu"] = 1e3 * cpu / steps
    return {"setup_s": setup, "total_s": setup + loop, "per_step_ms": per_step, "threads": report.get("threads", 1),
            "cg_iterations": (report["nutrient_cg_iterations"] - counts["nutrient_cg_iterations"]) / steps,
            "bicgstab_iterations": (report["biofilm_iterations"] - counts["biofilm_iterations"]) / steps,
            "amg_rebuilds": report["nutrient_amg_rebuilds"]}


def measure_fipy(n: int, steps: int, solvers: str, ndim: int) -> dict:
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "tests"))
    from fipy_reference import FipyTransport  # the plain-FiPy reference lives beside the tests that use it

    reference = FipyTransport(directional(n, steps, "upwind", "pointwise", ndim), solvers=solvers)
    reference.solve_nutrient()
    start = time.perf_counter()
    for _ in range(steps):
        reference.step(DT)
    return {"per_step_ms": 1e3 * (time.perf_counter() - start) / steps}


def one(args) -> None:
    """Child process: one measurement, printed as JSON with the peak memory."""
    if args.one == "fast":
        result = measure_fast(args.n, args.steps, args.advection, args.velocity, args.ndim, args.threads)
    else:
        result = measure_fipy(args.n, args.steps, args.one, args.ndim)
    result["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps(result))


def child(kind: str, n: int, steps: int, ndim: int, advection: str = "tvd", velocity: str = "pointwise",
          baseline: str | None = None, threads: int | None = None) -> dict:
    """One case in a fresh process; `baseline`: a directory put first on the path (another version's solver)."""
    command = [sys.executable, os.path.abspath(__file__), "--one", kind, "--n", str(n), "--steps", str(steps),
               "--ndim", str(ndim), "--advection", advection, "--velocity", velocity,
               *(["--threads", str(threads)] if threads and not baseline else [])]
    path = [os.path.abspath(baseline)] if baseline else []
    load = os.getloadavg()[0]
    out = subprocess.run(command, check=True, capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": os.pathsep.join(path + sys.path)})
    return {**json.loads(out.stdout.strip().splitlines()[-1]), "load": load}


def cases(args) -> list[tuple[int, int]]:
    """(n, ndim) of every grid asked for, smallest first within each dimension."""
    return [(n, 3) for n in args.sizes] + [(n, 2) for n in args.sizes_2d]


def steps_for(args, n: int, ndim: int) -> int:
    smallest = (args.sizes if ndim == 3 else args.sizes_2d)[0]
    return max(args.min_steps, int(args.steps * (smallest / n) ** ndim))


def cells(n: int, ndim: int) -> str:
    return f"{n}^{ndim}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="*", default=[20, 40], help="3-D grids: n^3 cells")
    parser.add_argument("--sizes-2d", type=int, nargs="*", default=[], help="2-D grids: n^2 cells")
    parser.add_argument("--steps", type=int, default=100, help="steps timed at the smallest size (fewer above)")
    parser.add_argument("--min-steps", type=int, default=20, help="steps timed at least, at any size")
    parser.add_argument("--fipy-sizes", type=int, nargs="*", default=[20],
                        help="3-D sizes also run by plain FiPy with CG/GMRES")
    parser.add_argument("--fipy-default-sizes", type=int, nargs="*", default=[20],
                        help="3-D sizes also run with FiPy's default (LU) solvers; 40^3 costs ~30 s per step")
    parser.add_argument("--fipy-steps", type=int, default=5)
    parser.add_argument("--advection", default="tvd", choices=["upwind", "tvd"])
    parser.add_argument("--growth-velocity", nargs="+", default=["front", "pointwise"], choices=["front", "pointwise"])
    parser.add_argument("--baseline", help="directory holding another version's solver/ (and biostudy/)")
    parser.add_argument("--threads", type=int, help="this version's threads (default: the processors here; a "
                                                    "baseline before threads runs on one)")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    parser.add_argument("--velocity", default="pointwise", help=argparse.SUPPRESS)
    parser.add_argument("--n", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--ndim", type=int, default=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        return one(args)

    rows = []
    for n, ndim in cases(args):
        steps = steps_for(args, n, ndim)
        fipy = {}
        if ndim == 3 and n in args.fipy_sizes:
            fipy["iterative"] = child("iterative", n, args.fipy_steps, ndim)
        if ndim == 3 and n in args.fipy_default_sizes:
            fipy["default"] = child("default", n, args.fipy_steps, ndim)
        for velocity in args.growth_velocity:
            this = child("fast", n, steps, ndim, args.advection, velocity, threads=args.threads)
            old = child("fast", n, steps, ndim, args.advection, velocity, args.baseline) if args.baseline else None
            rows.append((n, ndim, velocity, steps, this, old, fipy))
            print(f"# {cells(n, ndim)} {velocity}: {this['per_step_ms']['total']:.1f} ms/step (load {this['load']:.1f})"
                  + (f", baseline {old['per_step_ms']['total']:.1f} (load {old['load']:.1f})" if old else ""),
                  file=sys.stderr, flush=True)

    print(f"directional scene, mechanics off, dt = {DT:g}, advection = {args.advection}, "
          f"FIPY_SOLVERS = {os.environ['FIPY_SOLVERS']}, OMP_NUM_THREADS = {os.environ['OMP_NUM_THREADS']}")
    print("| cells | growth velocity | version | threads | load | steps | nutrient | velocity | phi solve "
          "| bookkeeping | **total ms/step** | CPU ms/step | CG its/solve | BiCGSTAB its | AMG builds | setup s "
          "| peak MB | baseline / this (wall, CPU) | set-up + steps s | **this / baseline, set-up included** |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n, ndim, velocity, steps, this, old, _ in rows:
        versions = [("this", this)] + ([("baseline", old)] if old else [])
        for label, r in versions:
            s = r["per_step_ms"]
            ratio, whole = "", ""
            if old and label == "this":
                wall, cpu = (old["per_step_ms"][k] / this["per_step_ms"][k] for k in ("total", "cpu"))
                ratio = f"**{wall:.2f}×**, {cpu:.2f}×"
                if "total_s" in old:
                    whole = f"**{this['total_s'] / old['total_s']:.2f}**"
            print(f"| {cells(n, ndim)} | {velocity} | {label} | {r.get('threads', 1)} | {r['load']:.1f} | {steps} | "
                  f"{s['nutrient']:.1f} | {s['velocity']:.1f} | {s['biofilm']:.1f} | {s['bookkeeping']:.1f} | "
                  f"**{s['total']:.1f}** | {s['cpu']:.1f} | {r['cg_iterations']:.1f} | "
                  f"{r['bicgstab_iterations']:.1f} | "
                  f"{r['amg_rebuilds']} | {r['setup_s']:.2f} | {r['peak_mb']:.0f} | {ratio} | "
                  f"{r.get('total_s', float('nan')):.2f} | {whole} |")
    fipy_rows = [(n, velocity, this, fipy) for n, ndim, velocity, _, this, _, fipy in rows if fipy]
    if fipy_rows:
        print("\n| cells | growth velocity | this ms/step | plain FiPy CG/GMRES ms/step | FiPy default (LU) ms/step "
              "| speed-up vs CG/GMRES | speed-up vs LU |")
        print("|---|---|---|---|---|---|---|")
        for n, velocity, this, fipy in fipy_rows:
            total = this["per_step_ms"]["total"]
            cols = [f"{fipy[k]['per_step_ms']:.0f}" if k in fipy else "not run" for k in ("iterative", "default")]
            ups = [f"{fipy[k]['per_step_ms'] / total:.0f}×" if k in fipy else "–" for k in ("iterative", "default")]
            print(f"| {n}^3 | {velocity} | {total:.1f} | {cols[0]} | {cols[1]} | {ups[0]} | {ups[1]} |")
    for ndim in (3, 2):
        for velocity in args.growth_velocity:
            for label, index in (("this", 4), ("baseline", 5)):
                mine = [r for r in rows if r[1] == ndim and r[2] == velocity and r[index]]
                if len(mine) > 1:
                    first, last = mine[0], mine[-1]
                    exponent = (np.log(last[index]["per_step_ms"]["total"] / first[index]["per_step_ms"]["total"])
                                / np.log((last[0] / first[0]) ** ndim))
                    print(f"\n{velocity}, {label}: cost per step grows as N^{exponent:.2f} in the cell count N between "
                          f"{cells(first[0], ndim)} and {cells(last[0], ndim)}")


if __name__ == "__main__":
    main()
