"""What the nutrient solve's parts are worth (issue 20): prints tables.

    python benchmarks/nutrient.py                      # 40^3: solver variants on a recorded run
    python benchmarks/nutrient.py --n 20 --tolerances  # 20^3: the whole run at nutrient tolerances 1e-13 ... 1e-6

Solver variants: the directional scene of benchmarks/transport.py (TVD, front
velocity) is run for --steps steps and the (phi, c) of every step recorded;
then the nutrient systems of the second half of the run are solved again,
each from the previous step's c, by
  * scipy's CG with pyamg's V-cycle (symmetric Gauss-Seidel on both sides, the
    hierarchy's own fine matrix) -- the solve before issue 20;
  * the same with one forward sweep before and one backward sweep after;
  * solver.transport.linear's PCG and VCycle (those sweeps, the fine level on
    the matrix being solved), every level smoothed, started from c^n and from
    c^n extrapolated along its last change (c^n + (c^n - c^(n-1)));
  * the cycle passing through Ruge-Stueben's first coarse level, with the
    coarsest level at most 50 or 200 rows, from the line and from the parabola
    through the last three c's (3 c^n - 3 c^(n-1) + c^(n-2): what
    Transport.step does), at pyamg's default strength 0.25 and at 0.1 (now);
  * that cycle on Ruge-Stueben's second pass (rejected);
  * pyamg's smoothed aggregation, and Ruge-Stueben with strength 0.5;
each with its CG iterations, ms per solve and relative initial residual, at
tolerance 1e-10 (the true residual checked).  Also the cost of forming
K + gamma diag(phi) as a new CSR matrix against rewriting a kept one.

--tolerances: the bundled directional scene (studies/directional.toml, its
1000 steps, mechanics off; on --n^3 cells) run at nutrient tolerances 1e-13,
1e-10, 1e-8, 1e-6; phi and c at every output against the 1e-13 run: what the
growth direction needs of the nutrient.
Asserts nothing.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time

os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pyamg  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402
from transport import directional  # noqa: E402

TOLERANCE = 1e-10
DEFAULT = ("classical", {"theta": 0.25})  # pyamg's default strength of connection


def record(n: int, steps: int):
    """The nutrient's K, rhs, free cells and gamma, and phi, c (active cells) after every solve of a run."""
    from solver import Simulation

    run = Simulation(directional(n, steps, "tvd", "front"))
    nutrient = run.transport.nutrient
    phis, cs, solve = [], [], nutrient.solve

    def recording(phi, guess=None):
        c = solve(phi, guess)
        phis.append(phi.copy())
        cs.append(c.copy())
        return c

    nutrient.solve = recording
    for _ in run:
        pass
    return nutrient, np.array(phis), np.array(cs)


def scipy_cg(matrix, rhs, x0, hierarchy):
    count = [0]
    x, _ = spla.cg(matrix, rhs, x0=x0, rtol=TOLERANCE, atol=0.0, maxiter=500,
                   M=hierarchy.aspreconditioner(cycle="V"), callback=lambda _: count.__setitem__(0, count[0] + 1))
    return x, count[0]


def variants(first):
    from solver.transport.krylov import pcg
    from solver.transport.linear import COARSEST, STRENGTH, VCycle

    forward, backward = ("gauss_seidel", {"sweep": "forward"}), ("gauss_seidel", {"sweep": "backward"})

    def with_pyamg(build):
        hierarchy = build(first)
        return lambda matrix, rhs, x0: scipy_cg(matrix, rhs, x0, hierarchy)

    def own(passed=(1,), coarsest=COARSEST, strength=STRENGTH):
        cycle = VCycle(pyamg.ruge_stuben_solver(first, max_coarse=coarsest, strength=strength), passed)

        def solve(matrix, rhs, x0):
            x, its, _, _ = pcg(matrix, rhs, x0.copy(), lambda r: cycle(matrix, r), TOLERANCE * np.linalg.norm(rhs), 500)
            return x, its
        return solve

    def own_with(**kw):
        cycle = VCycle(pyamg.ruge_stuben_solver(first, max_coarse=COARSEST, strength=STRENGTH, **kw))

        def solve(matrix, rhs, x0):
            x, its, _, _ = pcg(matrix, rhs, x0.copy(), lambda r: cycle(matrix, r), TOLERANCE * np.linalg.norm(rhs), 500)
            return x, its
        return solve

    rs = lambda **kw: lambda m: pyamg.ruge_stuben_solver(m, max_coarse=50, **kw)  # noqa: E731
    return [
        ("scipy CG, pyamg RS V-cycle, symmetric GS (before issue 20)", with_pyamg(rs()), 0),
        ("scipy CG, pyamg RS V-cycle, forward/backward GS", with_pyamg(rs(presmoother=forward, postsmoother=backward)),
         0),
        ("own PCG + VCycle, every level smoothed, from c^n", own((), 50, DEFAULT), 0),
        ("the same from c^n extrapolated along dc/dt (before the level was passed)", own((), 50, DEFAULT), 1),
        ("passing level 1, from the line", own((1,), 50, DEFAULT), 1),
        ("passing level 1, coarsest level <= 200 rows, from the line", own(strength=DEFAULT), 1),
        ("passing level 1, coarsest level <= 200 rows, from the parabola", own(strength=DEFAULT), 2),
        ("the same with strength 0.1 (now)", own(), 2),
        ("now, but Ruge-Stueben's second pass", own_with(CF=("RS", {"second_pass": True})), 2),
        ("scipy CG, pyamg smoothed aggregation", with_pyamg(lambda m: pyamg.smoothed_aggregation_solver(
            m, max_coarse=50)), 0),
        ("scipy CG, pyamg RS strength 0.5, fw/bw GS", with_pyamg(rs(strength=("classical", {"theta": 0.5}),
                                                                   presmoother=forward, postsmoother=backward)),
         0),
    ]


def solver_table(n: int, steps: int) -> None:
    from solver.transport.linear import KeptDiagonal

    nutrient, phis, cs = record(n, steps)
    free, rhs, gamma, K = nutrient.free, nutrient.rhs, nutrient.gamma, nutrient.stiffness
    matrices = [sp.csr_matrix(K + sp.diags(gamma * phi[free])) for phi in phis]
    solves = range(len(phis) // 2, len(phis))
    print(f"directional scene {n}^3 (TVD, front velocity), nutrient solves {solves.start}-{solves.stop - 1} of "
          f"{len(phis)}, tolerance {TOLERANCE:g}, load average {os.getloadavg()[0]:.1f}")
    print("| solver | CG its/solve | ms/solve (CPU) | initial residual / |b| |")
    print("|---|---|---|---|")
    norm = np.linalg.norm(rhs)
    with threadpool_limits(limits=1, user_api="blas"):
        for name, solve, order in variants(matrices[0]):  # order of the extrapolation in time: 0, 1, 2
            its, residuals, began, cpu = 0, [], time.perf_counter(), time.process_time()
            for k in solves:
                x0 = (cs[k - 1], 2 * cs[k - 1] - cs[k - 2], 3 * cs[k - 1] - 3 * cs[k - 2] + cs[k - 3])[order][free]
                residuals.append(np.linalg.norm(rhs - matrices[k] @ x0) / norm)
                x, count = solve(matrices[k], rhs, x0)
                its += count
                assert np.linalg.norm(rhs - matrices[k] @ x) <= TOLERANCE * norm, name
            ms = 1e3 * (time.perf_counter() - began) / len(solves)
            cpu_ms = 1e3 * (time.process_time() - cpu) / len(solves)
            print(f"| {name} | {its / len(solves):.2f} | {ms:.1f} ({cpu_ms:.1f}) | {np.median(residuals):.1e} |",
                  flush=True)
        kept, demand = KeptDiagonal(K), gamma * phis[-1][free]
        for name, build in (("K + diag(gamma phi) as a new CSR matrix", lambda: sp.csr_matrix(K + sp.diags(demand))),
                            ("kept matrix, diagonal rewritten (KeptDiagonal)", lambda: kept(demand))):
            began = time.perf_counter()
            for _ in range(50):
                build()
            print(f"| {name} | – | {1e3 * (time.perf_counter() - began) / 50:.2f} | – |")


def bundled_directional(n: int):
    """studies/directional.toml on n^3 cells of 20/n µm, its 1000 steps, mechanics off."""
    from biostudy.inputs import bundled
    from biostudy.inputs.scene import load_scene

    overrides = [f"grid.shape=[{n},{n},{n}]", f"grid.spacing={20 / n!r}", "mechanics.enabled=false"]
    return load_scene(bundled.resolve("directional"), overrides).problem()


def tolerance_table(n: int) -> None:
    from solver import Simulation

    runs = {}
    for tolerance in (1e-13, 1e-10, 1e-8, 1e-6):
        problem = bundled_directional(n)
        problem = dataclasses.replace(problem, numerics=dataclasses.replace(problem.numerics,
                                                                            nutrient_tolerance=tolerance))
        run = Simulation(problem)
        began = time.perf_counter()
        snapshots = list(run)
        runs[tolerance] = (snapshots, run.report(), time.perf_counter() - began)
    reference = runs[1e-13][0]
    print(f"bundled directional scene (TVD, front velocity) on {n}^3 cells, its {problem.steps} steps to T* = "
          f"{problem.t_end:g}, mechanics off, against the run at tolerance 1e-13, largest differences over its "
          f"{len(reference)} outputs; load average {os.getloadavg()[0]:.1f}")
    print("| nutrient tolerance | CG its/solve | max abs(phi - phi_ref) | max abs(c - c_ref) | mean phi difference "
          "| s |")
    print("|---|---|---|---|---|---|")
    for tolerance, (snapshots, report, seconds) in runs.items():
        its = report["nutrient_cg_iterations"] / (report["steps_taken"] + 1)
        pairs = list(zip(snapshots, reference))
        dphi = max(np.nanmax(np.abs(a.phi - b.phi)) for a, b in pairs)
        dc = max(np.nanmax(np.abs(a.c - b.c)) for a, b in pairs)
        mean = max(abs(np.nanmean(a.phi) - np.nanmean(b.phi)) for a, b in pairs)
        print(f"| {tolerance:g} | {its:.2f} | {dphi:.1e} | {dc:.1e} | {mean:.1e} | {seconds:.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=40, help="cells per axis")
    parser.add_argument("--steps", type=int, default=100, help="steps of the recorded run (solver variants)")
    parser.add_argument("--tolerances", action="store_true", help="the tolerance table instead (whole runs)")
    args = parser.parse_args()
    if args.tolerances:
        tolerance_table(args.n)
    else:
        solver_table(args.n, args.steps)


if __name__ == "__main__":
    main()
