"""Cost of a mechanics snapshot, this version beside the first one: prints tables.

    python benchmarks/mechanics.py                                   # 20^3, 40^3, 60^3; alpha = 1e-3, 1e-2 phi
    python benchmarks/mechanics.py --baseline /tmp/first             # the same for the first version, side by side
    python benchmarks/mechanics.py --in-run 20 --baseline /tmp/first # the directional scene in its time loop
    python benchmarks/mechanics.py --sizes 40 --k 0.2                # a one-shot growth to alpha = 0.2
    python benchmarks/mechanics.py --sizes 20 --settings pin_in_biofilm=False   # a heuristic switched off

The first version is main's commit 5786d0c (extract it with
`git archive 5786d0c | tar -x -C /tmp/first`); --baseline DIR runs the same
cases with DIR's `solver` and `biostudy` first on the path.  Every case runs
in a fresh process under /usr/bin/time -v (peak memory: the case's own, its
setup included), cases of the two versions one after the other; the load
average before each case is printed, since the machine is shared.

Static cases: a cube of 20 µm in n^3 cells, phi = 1 in a sphere of radius
5 µm at the centre, smoothed over one cell (phi = clip(1/2 - (r - 5)/h, 0, 1)),
alpha = k phi, no clamp (rigid-body modes removed), Table 2 parameters.  Per
case: the one-off setup (mesh, constraints, sparsity pattern), the first
snapshot from rest and a second one warm-started from it with alpha grown by
10 %, each with its wall and CPU seconds, Newton steps and Krylov iterations.
A case that fails or runs past --timeout is reported as such.  --settings
KEY=VALUE changes this version's `solver.mechanics.Settings` (a heuristic
or a cap), to measure what it is worth.

--in-run N runs the bundled directional scene (studies/directional.toml,
TVD, 200 steps to T* = 1 unless --steps says otherwise (the scene itself
has 1000), mechanics at every 0.2 T*) on N^3 cells: there phi
itself moves between snapshots, which the static cases leave out.  Each
version runs the scene file bundled with it: since issue 9 this version's
grows with growth_velocity = "front", which the first version does not know
(it runs its own file, the pointwise velocity), so phi differs.  Prints
each snapshot's seconds and the run's total mechanics time.  Asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from fresh import header, run_case


def scene(n: int):
    from solver import Grid

    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    r = np.sqrt((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2)
    return grid, np.clip(0.5 - (r - 5.0) / grid.spacing, 0.0, 1.0)


def _krylov(info: dict) -> int:
    return info.get("krylov_iterations", info.get("gmres_iterations", -1))  # the first version said gmres


def settings(pairs: list[str]) -> dict:
    """{"settings": Settings(...)} from KEY=VALUE pairs (values parsed as Python literals), or {}."""
    if not pairs:
        return {}
    import ast

    from solver.mechanics import Settings

    return {"settings": Settings(**{k: ast.literal_eval(v) for k, v in (pair.split("=", 1) for pair in pairs)})}


def measure(n: int, k: float, changes: list[str]) -> dict:
    from solver import MechanicsSetup, Parameters
    from solver.mechanics import GrowthMechanics

    grid, phi = scene(n)
    began = time.perf_counter()
    mechanics = GrowthMechanics(grid, Parameters(), MechanicsSetup(), None, **settings(changes))
    out = {"setup_s": time.perf_counter() - began, "dofs": mechanics.mesh.n_dofs, "snapshots": []}
    for t in (1.0, 1.1):  # alpha = k phi t: the second snapshot has grown by 10 %
        cpu = time.process_time()
        result = mechanics.solve(phi, k * t * phi, t)
        out["snapshots"].append({
            "seconds": result.seconds, "cpu": time.process_time() - cpu, "newton": result.newton_iterations,
            "krylov": _krylov(result.info), "solver": result.info["linear_solver"],
            "p_min": float(np.nanmin(result.p)), "u_max": float(np.nanmax(np.abs(result.u))),
        })
    return out


def in_run(n: int, steps: int, changes: list[str]) -> dict:
    import biostudy

    # the first version (--baseline) calls it biostudy.catalog; asked for biostudy.inputs.bundled, the editable
    # install's finder would hand it this version's module, and so this version's scene file
    if (Path(biostudy.__file__).parent / "inputs" / "bundled.py").exists():
        from biostudy.inputs import bundled
    else:
        from biostudy import catalog as bundled
    from biostudy.inputs.scene import load_scene
    try:  # `Simulation` since the house was regrouped (0.2.0), `Run` before
        from solver.timeloop import Simulation as Run
    except ImportError:
        from solver import Run

    scene = load_scene(bundled.resolve("directional"), [f"grid.shape=[{n},{n},{n}]", f"grid.spacing={20 / n!r}",
                                                        f"time.steps={steps}", "time.outputs=6", "mechanics.every=1"])
    problem = scene.problem()
    run = Run(problem)
    if changes:
        from solver.mechanics import GrowthMechanics

        run.mechanics = GrowthMechanics(problem.grid, problem.params, problem.mechanics, problem.obstacle,
                                        **settings(changes))
    cpu, solve = [], run.mechanics.solve

    def timed(*args):  # the CPU seconds of each mechanics solve: the machine is shared
        began = time.process_time()
        result = solve(*args)
        cpu.append(time.process_time() - began)
        return result

    run.mechanics.solve = timed
    rows = []
    for snapshot in run:
        m = snapshot.mechanics
        rows.append({"time": snapshot.time, "seconds": m["seconds"], "cpu": cpu[-1], "newton": m["newton_iterations"],
                     "krylov": _krylov(m), "solver": m["linear_solver"]})
    report = run.report()
    return {"snapshots": rows, "mechanics_s": report["timings"]["mechanics"], "mechanics_cpu": sum(cpu),
            "wall_s": report["wall_time"]}


def static_table(args):
    versions = [("this", None)] + ([("first", args.baseline)] if args.baseline else [])
    extra = ["--settings", *args.settings] if args.settings else []
    header(f"{'cells':>6} {'dofs':>7} {'k':>6} {'version':<7} {'load':>4} {'setup s':>7} {'snap1 s':>7} {'cpu':>6} "
           f"{'newton':>6} {'krylov':>6} {'snap2 s':>7} {'cpu':>6} {'newton':>6} {'krylov':>6} {'peak GB':>7}  solver")
    for n in args.sizes:
        for k in args.k:
            for label, path in versions:
                r = run_case(__file__, ["--case", str(n), str(k)] + (extra if path is None else []), path, args.timeout)
                if "error" in r:
                    print(f"{n:>4}^3 {'':>7} {k:>6.0e} {label:<7} {r['load']:>4.1f} {r['error']}", flush=True)
                    continue
                s1, s2 = r["snapshots"]
                print(f"{n:>4}^3 {r['dofs']:>7} {k:>6.0e} {label:<7} {r['load']:>4.1f} {r['setup_s']:>7.2f} "
                      f"{s1['seconds']:>7.2f} {s1['cpu']:>6.2f} {s1['newton']:>6} {s1['krylov']:>6} "
                      f"{s2['seconds']:>7.2f} {s2['cpu']:>6.2f} {s2['newton']:>6} {s2['krylov']:>6} "
                      f"{r['peak_gb']:>7.2f}  {s1['solver']}", flush=True)


def in_run_table(args):
    versions = [("this", None)] + ([("first", args.baseline)] if args.baseline else [])
    extra = ["--settings", *args.settings] if args.settings else []
    results = {label: run_case(__file__, ["--run", str(args.in_run), "--steps", str(args.steps)]
                               + (extra if path is None else []), path, args.timeout) for label, path in versions}
    print(f"directional scene {args.in_run}^3 in its time loop (TVD, {args.steps} steps), mechanics at every 0.2 T*")
    for label, r in results.items():
        if "error" in r:
            print(f"{label} version (load {r['load']:.1f}): {r['error']}")
            continue
        print(f"{label} version (load {r['load']:.1f}, {r['snapshots'][-1]['solver']}): "
              f"mechanics {r['mechanics_s']:.2f} s "
              f"(cpu {r['mechanics_cpu']:.2f} s) of {r['wall_s']:.1f} s, peak {r['peak_gb']:.2f} GB")
        print(f"  {'T*':>4} {'seconds':>8} {'cpu':>6} {'newton':>6} {'krylov':>6}")
        for row in r["snapshots"]:
            print(f"  {row['time']:>4.1f} {row['seconds']:>8.2f} {row['cpu']:>6.2f} {row['newton']:>6} "
                  f"{row['krylov']:>6}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40, 60])
    parser.add_argument("--k", type=float, nargs="+", default=[1e-3, 1e-2])
    parser.add_argument("--baseline", help="directory holding the first version's solver/ and biostudy/")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds before a case is stopped")
    parser.add_argument("--in-run", type=int, metavar="N", help="the directional scene's run on N^3")
    parser.add_argument("--steps", type=int, default=200, help="--in-run: time steps (the bundled scene: 1000)")
    parser.add_argument("--settings", nargs="+", default=[], metavar="KEY=VALUE",
                        help="this version's solver.mechanics.Settings changed")
    parser.add_argument("--case", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--run", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(json.dumps(measure(int(args.case[0]), float(args.case[1]), args.settings)))
    elif args.run:
        print(json.dumps(in_run(args.run, args.steps, args.settings)))
    elif args.in_run:
        in_run_table(args)
    else:
        static_table(args)


if __name__ == "__main__":
    main()
