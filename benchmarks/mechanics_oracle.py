"""The mechanics' own assembler against the scikit-fem forms of its oracle (tests/mechanics_oracle.py): prints a table.

    python benchmarks/mechanics_oracle.py                  # 8^3, 12^3, 20^3
    python benchmarks/mechanics_oracle.py --sizes 8 12 --no-check

One residual and consistent tangent of the growth problem (paper 2.1, 2.3.1, 3) on n^3 cells of 1 µm,
no constraints, at a random displacement (0.02 µm per component), random phi (a third of the cells
void) and alpha in [0, 0.2]: `solver.mechanics.assembly.Assembler.evaluate` (best of --repeat) and
`MechanicsOracle.evaluate` (once), wall and CPU seconds of this process with one BLAS thread (as in a
mechanics solve); setup (mesh, pattern, bases) apart.  The machine is shared: the load average before
each case is printed.  Then, unless --no-check, the agreement: the largest difference of residual and
tangent entries in unit round-offs of each entry's own scale (the bound of the test, `roundings`, beside it).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "tests"))
from mechanics_oracle import MechanicsOracle, roundings, roundoff_ratio  # noqa: E402  the oracle lives beside its test

from solver import Grid, MechanicsSetup, Parameters  # noqa: E402
from solver.mechanics import material  # noqa: E402
from solver.mechanics.assembly import Assembler  # noqa: E402
from solver.mechanics.mesh import StructuredMesh  # noqa: E402

PARAMS = Parameters()
EPS = MechanicsSetup().residual_stiffness


def timed(call, repeat: int = 1):
    """(result, wall s, CPU s) of the fastest of `repeat` calls."""
    best = None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        result = call()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        if best is None or wall < best[1]:
            best = (result, wall, cpu)
    return best


def case(n: int, repeat: int, check: bool) -> dict:
    grid = Grid((n, n, n), 1.0)
    rng = np.random.default_rng(n)
    phi = np.where(rng.uniform(size=grid.cells_shape) < 1 / 3, 0.0, rng.uniform(0, 1, grid.cells_shape))
    alpha = rng.uniform(0, 0.2, grid.cells_shape)
    load = os.getloadavg()[0]
    mesh, setup_ours, _ = timed(lambda: StructuredMesh(grid))
    assembler, setup_a, _ = timed(lambda: Assembler(mesh, np.zeros(mesh.n_dofs, bool)))
    oracle, setup_theirs, _ = timed(lambda: MechanicsOracle(grid.shape, grid.spacing))
    u = 0.02 * rng.standard_normal(mesh.n_dofs)
    order = oracle.dofs_at(mesh.node_coordinates()).ravel()
    u_o = np.zeros(oracle.u_basis.N)
    u_o[order] = u
    w, growth = material.weight(phi.ravel()[mesh.cells], EPS), (1 + alpha.ravel()[mesh.cells]) ** 3
    ours, wall_ours, cpu_ours = timed(lambda: assembler.evaluate(u, w, growth, PARAMS.mu, PARAMS.kappa), repeat)
    theirs, wall_theirs, cpu_theirs = timed(lambda: oracle.evaluate(u_o, phi, alpha, PARAMS.mu, PARAMS.kappa, EPS))
    row = {"n": n, "dofs": mesh.n_dofs, "load": load, "setup_ours": setup_ours + setup_a, "setup_theirs": setup_theirs,
           "wall_ours": wall_ours, "cpu_ours": cpu_ours, "wall_theirs": wall_theirs, "cpu_theirs": cpu_theirs}
    if check:
        scale = oracle.magnitudes(u_o, phi, alpha, PARAMS.mu, PARAMS.kappa, EPS)
        row["residual"] = roundoff_ratio(ours.residual, theirs.residual[order], scale.residual[order])
        row["tangent"] = roundoff_ratio(ours.matrix.tocsr(), theirs.tangent[order][:, order],
                                        scale.tangent[order][:, order])
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[8, 12, 20])
    parser.add_argument("--repeat", type=int, default=3, help="best of this many evaluations of the own assembler")
    parser.add_argument("--no-check", action="store_true", help="skip the agreement (one more oracle assembly)")
    args = parser.parse_args()
    with threadpool_limits(limits=1, user_api="blas"):
        rows = [case(n, args.repeat, not args.no_check) for n in args.sizes]
    print("residual + tangent, one BLAS thread; agreement in unit round-offs of each entry's scale")
    print("| cells | dofs | load | own assembler s (CPU) | scikit-fem forms s (CPU) | ratio | setup own / scikit-fem s "
          "| agreement residual / tangent |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        agreement = (f"{r['residual']:.1f} / {r['tangent']:.1f} (bound {roundings((r['n'],) * 3)})" if "tangent" in r
                     else "not checked")
        dofs = f"{r['dofs']:,}".replace(",", " ")
        print(f"| {r['n']}³ | {dofs} | {r['load']:.1f} | {r['wall_ours']:.3f} ({r['cpu_ours']:.3f}) | "
              f"{r['wall_theirs']:.2f} ({r['cpu_theirs']:.2f}) | {r['wall_theirs'] / r['wall_ours']:.0f}× | "
              f"{r['setup_ours']:.2f} / {r['setup_theirs']:.2f} | {agreement} |")


if __name__ == "__main__":
    main()
