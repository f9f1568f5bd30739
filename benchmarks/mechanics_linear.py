"""Preconditioners for the mechanics' linear solves, side by side on one realistic tangent: prints a table.

    python benchmarks/mechanics_linear.py                  # 20^3 and 40^3
    python benchmarks/mechanics_linear.py --sizes 20 --rtol 1e-3

Scene: the snapshot benchmark's sphere (radius 5 µm in a 20 µm cube, one-cell
smooth edge, no clamp), alpha = 1e-3 phi solved to equilibrium; then the
system of the next snapshot (alpha grown by 10 %): the tangent with the
start's stress and its residual, which is what a snapshot of a run solves
first.  Each preconditioner in a fresh process (peak memory from
/usr/bin/time -v), with one BLAS thread as in a mechanics solve: its build
time, then scipy's CG to |r| <= rtol |b|: iterations, time, time per
iteration (wall and CPU seconds of the process: the machine is shared; the
load average before each case is printed).  The direct factorisation is skipped
beyond 30^3 (it needs several GB there).

Preconditioners (solver/mechanics/preconditioners.py): "direct" (PARDISO or
SuperLU), "multigrid" (geometric, Galerkin coarse grids, Chebyshev smoothing
of degree 3, the default), "multigrid-2" (degree 2), "multigrid-gs" (pyamg's
block Gauss-Seidel, 2 sweeps before and after: the first version's
smoother), "amg" (pyamg smoothed aggregation, rigid-body modes as near-null
space, symmetric block Gauss-Seidel), "amg-scalar" (the same with pyamg's
default near-null space, one constant per displacement component).
"""
from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from fresh import header, run_case

METHODS = ("direct", "multigrid", "multigrid-2", "multigrid-gs", "amg", "amg-scalar")


def system(n: int):
    """(mechanics, tangent, right-hand side) of the second snapshot of the sphere on n^3 cells."""
    from solver import Grid, MechanicsSetup, Parameters
    from solver.mechanics import GrowthMechanics

    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    phi = np.clip(0.5 - (np.sqrt((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2) - 5.0) / grid.spacing, 0.0, 1.0)
    mechanics = GrowthMechanics(grid, Parameters(), MechanicsSetup(linear_solver="multigrid"))
    mechanics.solve(phi, 1e-3 * phi, 1.0)
    phi_e = phi.ravel()[mechanics.mesh.cells]
    operator = mechanics._evaluator(phi_e, mechanics.alpha)(mechanics.u, True).matrix
    rhs = -mechanics._evaluator(phi_e, 1.1 * mechanics.alpha)(mechanics.u, False).residual
    return mechanics, operator, rhs


def preconditioner(method: str, mechanics):
    from solver.mechanics import preconditioners as pc
    from solver.mechanics.constraints import rigid_modes

    mesh, fixed = mechanics.mesh, mechanics.fixed
    if method == "direct":
        return pc.Direct()
    if method.startswith("multigrid"):
        M = pc.GeometricMultigrid(mesh, fixed, coarsest=1000, degree=2 if method.endswith("-2") else 3)
        if method.endswith("-gs"):
            M.cycle._smooth = gauss_seidel
        return M
    modes = rigid_modes((mesh.node_coordinates() - mesh.node_coordinates().mean(axis=0)) / mesh.h)
    if method == "amg-scalar":  # pyamg's default near-null space: one constant per unknown in a block
        modes = np.kron(np.ones((mesh.n_nodes, 1)), np.eye(mesh.ndim))
    return pc.SmoothedAggregation(modes, fixed, mesh.ndim, coarsest=1000)


def gauss_seidel(level, x, b, zero=False, sweeps=2):
    """Block Gauss-Seidel (pyamg's kernel), forward before the coarse correction, backward after."""
    from pyamg.amg_core import block_gauss_seidel

    d = level.Dinv.shape[1]
    n = level.A.shape[0] // d
    start, stop, step = (0, n, 1) if zero else (n - 1, -1, -1)
    for _ in range(sweeps):
        block_gauss_seidel(level.A.indptr, level.A.indices, level.A.data.ravel(), x, b, level.Dinv.ravel(),
                           start, stop, step, d)


def measure(n: int, method: str, rtol: float) -> dict:
    import scipy.sparse.linalg as spla
    from threadpoolctl import threadpool_limits

    mechanics, A, b = system(n)
    M = preconditioner(method, mechanics)
    with threadpool_limits(limits=1, user_api="blas"):  # as in a mechanics solve (Settings.blas_threads)
        began, cpu = time.perf_counter(), time.process_time()
        M.build(A)
        build, build_cpu = time.perf_counter() - began, time.process_time() - cpu
        count = [0]
        began, cpu = time.perf_counter(), time.process_time()
        x, info = spla.cg(A, b, rtol=rtol, atol=0.0, maxiter=500, M=spla.LinearOperator(A.shape, M, dtype=float),
                          callback=lambda _: count.__setitem__(0, count[0] + 1))
        seconds, solve_cpu = time.perf_counter() - began, time.process_time() - cpu
    return {"dofs": int(A.shape[0]), "build_s": build, "build_cpu": build_cpu, "iterations": count[0],
            "solve_s": seconds, "solve_cpu": solve_cpu, "info": int(info),
            "achieved": float(np.linalg.norm(b - A @ x) / np.linalg.norm(b))}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 40])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--case", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.case:
        print(json.dumps(measure(int(args.case[0]), args.case[1], float(args.case[2]))))
        return
    print(f"load average {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores); CG to |r| <= {args.rtol:g} |b|")
    header(f"{'cells':>6} {'dofs':>7} {'preconditioner':<12} {'load':>4} {'build s':>7} {'cpu':>6} {'its':>4} "
           f"{'solve s':>7} {'cpu':>6} {'cpu ms/it':>9} {'peak GB':>7}")
    for n in args.sizes:
        for method in args.methods:
            if method == "direct" and n > 30:
                continue
            r = run_case(__file__, ["--case", str(n), method, str(args.rtol)])
            if "error" in r:
                print(f"{n:>4}^3 {'':>7} {method:<12} failed: {r['error']}")
                continue
            its = f"{r['iterations']:>4}" if r["info"] == 0 else f"{'>' + str(r['iterations']):>4}"
            print(f"{n:>4}^3 {r['dofs']:>7} {method:<12} {r['load']:>4.1f} {r['build_s']:>7.2f} {r['build_cpu']:>6.2f} "
                  f"{its} {r['solve_s']:>7.2f} {r['solve_cpu']:>6.2f} "
                  f"{1e3 * r['solve_cpu'] / max(r['iterations'], 1):>9.0f} {r['peak_gb']:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
