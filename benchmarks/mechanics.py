"""Cost of one mechanics snapshot on the directional scene (paper 4.1): prints a table.

    python benchmarks/mechanics.py                          # 20^3 and 40^3, k = 1e-3 and 1e-2, auto solver
    python benchmarks/mechanics.py --sizes 20 --solvers direct multigrid --k 1e-2
    python benchmarks/mechanics.py --sizes 20 --solvers direct-superlu auto-superlu   # without pypardiso
    python benchmarks/mechanics.py --in-run 20              # every snapshot of the bundled scene's own run

Scene: a cube of 20 µm in n^3 cells, phi = 1 in a sphere of radius 5 µm at the
centre, smoothed over one cell (phi = clip(1/2 - (r - 5)/h, 0, 1)),
alpha = k phi, no clamp (rigid-body modes removed), Table 2 parameters.
Per case, in a fresh process (so that peak memory is the case's own, read
from /usr/bin/time -v): the one-off setup (mesh, constraints, sparsity
pattern), the first snapshot from rest, and a second one warm-started from it
with alpha grown by 10 % (what the time loop does), each with its Newton and
GMRES iterations and preconditioner builds.  Asserts nothing: a table for
docs/mechanics.md.

--in-run N runs the bundled directional scene (studies/directional.toml,
TVD, 200 steps to T* = 1) on N^3 cells with the mechanics at every 0.2 T*
and prints each snapshot's cost: there phi itself moves between snapshots,
which the static cases above leave out.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np


def scene(n: int):
    from solver import Grid

    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    r = np.sqrt((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2)
    return grid, np.clip(0.5 - (r - 5.0) / grid.spacing, 0.0, 1.0)


def measure(n: int, k: float, solver: str) -> dict:
    from solver import MechanicsSetup, Parameters
    from solver.mechanics import GrowthMechanics, linear

    if solver.endswith("-superlu"):  # what a machine without pypardiso (not x86_64) gets
        linear.pypardiso = None
        solver = solver.removesuffix("-superlu")

    grid, phi = scene(n)
    began = time.perf_counter()
    mechanics = GrowthMechanics(grid, Parameters(), MechanicsSetup(linear_solver=solver), None)
    out = {"setup_s": time.perf_counter() - began, "dofs": mechanics.mesh.n_dofs, "snapshots": []}
    for t in (1.0, 1.1):  # alpha = k phi t: the second snapshot has grown by 10 %
        result = mechanics.solve(phi, k * t * phi, t)
        out["snapshots"].append({
            "seconds": result.seconds, "newton": result.newton_iterations,
            "gmres": result.info["gmres_iterations"], "builds": result.info["preconditioner_builds"],
            "load_steps": result.info["load_steps"], "solver": result.info["linear_solver"],
            "p_min": float(np.nanmin(result.p)), "p_max": float(np.nanmax(result.p)),
            "u_max": float(np.nanmax(np.abs(result.u))),
        })
    return out


def in_run(n: int) -> None:
    from biostudy import catalog
    from biostudy.scene import load_scene
    from solver import evolve

    scene = load_scene(catalog.resolve("directional"), [f"grid.shape=[{n},{n},{n}]", f"grid.spacing={20 / n!r}",
                                                        "time.steps=200", "time.outputs=6", "mechanics.every=1"])
    print(f"directional scene {n}^3 in its time loop: mechanics at every output")
    print(f"{'T*':>4} {'seconds':>8} {'newton':>6} {'gmres':>5} {'builds':>6} {'load steps':>10} {'cutbacks':>8}")
    for snapshot in evolve(scene.problem()):
        m = snapshot.mechanics
        if m.get("newton_iterations", 0) or snapshot.time > 0:
            print(f"{snapshot.time:>4.1f} {m['seconds']:>8.2f} {m['newton_iterations']:>6} {m['gmres_iterations']:>5} "
                  f"{m['preconditioner_builds']:>6} {m['load_steps']:>10} {m['load_cutbacks']:>8}", flush=True)


def run_case(n: int, k: float, solver: str) -> dict:
    """One case in a fresh process, under /usr/bin/time -v when it is there."""
    command = [sys.executable, __file__, "--case", str(n), str(k), solver]
    timer = shutil.which("time") or ("/usr/bin/time" if os.path.exists("/usr/bin/time") else None)
    if timer:
        command = [timer, "-v", *command]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else "failed"}
    result = json.loads(done.stdout.strip().splitlines()[-1])
    peak = re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr)
    result["peak_gb"] = int(peak.group(1)) / 1024**2 if peak else float("nan")
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40])
    parser.add_argument("--k", type=float, nargs="+", default=[1e-3, 1e-2])
    parser.add_argument("--solvers", nargs="+", default=["auto"],
                        choices=["auto", "direct", "multigrid", "auto-superlu", "direct-superlu", "multigrid-superlu"])
    parser.add_argument("--case", nargs=3, help=argparse.SUPPRESS)
    parser.add_argument("--in-run", type=int, metavar="N", help="snapshots of the directional scene's run on N^3")
    args = parser.parse_args()
    if args.in_run:
        in_run(args.in_run)
        return
    if args.case:
        n, k, solver = int(args.case[0]), float(args.case[1]), args.case[2]
        print(json.dumps(measure(n, k, solver)))
        return
    header = (f"{'cells':>6} {'dofs':>7} {'k':>6} {'solver':<32} {'setup s':>7} "
              f"{'snap1 s':>7} {'newton':>6} {'gmres':>5} {'snap2 s':>7} {'newton':>6} {'gmres':>5} "
              f"{'builds':>6} {'peak GB':>7}")
    print(header)
    print("-" * len(header))
    for n in args.sizes:
        for k in args.k:
            for solver in args.solvers:
                r = run_case(n, k, solver)
                if "error" in r:
                    print(f"{n:>4}^3 {'':>7} {k:>6.0e} {solver:<32} failed: {r['error']}")
                    continue
                s1, s2 = r["snapshots"]
                print(f"{n:>4}^3 {r['dofs']:>7} {k:>6.0e} {s1['solver']:<32} {r['setup_s']:>7.2f} "
                      f"{s1['seconds']:>7.2f} {s1['newton']:>6} {s1['gmres']:>5} "
                      f"{s2['seconds']:>7.2f} {s2['newton']:>6} {s2['gmres']:>5} "
                      f"{s1['builds'] + s2['builds']:>6} {r['peak_gb']:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
