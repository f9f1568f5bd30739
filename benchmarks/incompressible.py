"""Nearly incompressible growth (issue 33.4): one mechanics solve growing alpha from 0 to 0.2 in a sphere, by nu.

The directional scene's sphere (radius 5 µm in the 20 µm cube) at n³ cells, the mechanics at rest first (alpha =
0), then one solve to alpha = 0.2 phi: solved or refused, its wall time (`solve s`, the second solve alone), Newton
steps, Krylov iterations and preconditioner builds, and the diagnosis's last words.  Table 2's nu = 0.49 solves;
nearer 0.5 the growth's volumetric prestress 3 kappa alpha outgrows mu by thousands and the solve is refused, at
what cost against the solved one.  With `--every` the growth comes in that many equal solves instead (what the
diagnosis advises: more outputs, mechanics every one).

    python benchmarks/incompressible.py [--sizes 4 8 12] [--nu 0.49 0.495 0.499 0.4999] [--every 1 20]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from solver import Grid, MechanicsSetup, Parameters
from solver.errors import MechanicsError
from solver.mechanics import GrowthMechanics


def one(n: int, nu: float, pieces: int) -> dict:
    grid = Grid((n, n, n), 20.0 / n)
    x, y, z = grid.cell_coordinates()
    phi = (((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2) <= 25).astype(float)
    mechanics = GrowthMechanics(grid, Parameters(nu=nu), MechanicsSetup())
    mechanics.solve(phi, np.zeros_like(phi), 0.0)
    found = {"newton": 0, "krylov": 0, "builds": 0, "outcome": "solved", "said": ""}
    began = time.perf_counter()
    try:
        for i in range(1, pieces + 1):
            result = mechanics.solve(phi, 0.2 * i / pieces * phi, float(i))
            found["newton"] += result.newton_iterations
            found["krylov"] += result.info["krylov_iterations"]
            found["builds"] += result.info["preconditioner_builds"]
    except MechanicsError as error:
        found.update(outcome=f"refused at {i}/{pieces}", said=str(error).split("; ")[0][:60],
                     newton=found["newton"] + error.tried["newton"], krylov=found["krylov"] + error.tried["krylov"],
                     builds=found["builds"] + error.tried["builds"])
    found["seconds"] = time.perf_counter() - began
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 12])
    parser.add_argument("--nu", type=float, nargs="+", default=[0.49, 0.495, 0.499, 0.4999])
    parser.add_argument("--every", type=int, nargs="+", default=[1, 20], help="solves the growth comes in")
    args = parser.parse_args()
    print(f"load average before: {' '.join(open('/proc/loadavg').read().split()[:3])}")
    print("| cells | nu | kappa/mu | solves | outcome | solve s | against nu = 0.49 | Newton | Krylov | builds "
          "| diagnosis begins |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for pieces in args.every:
            base = None
            for nu in args.nu:
                row = one(n, nu, pieces)
                base = row["seconds"] if nu == 0.49 else base
                ratio = f"{row['seconds'] / base:.1f}x" if base else "-"
                print(f"| {n}³ | {nu:g} | {Parameters(nu=nu).kappa / Parameters(nu=nu).mu:.3g} | {pieces} | "
                      f"{row['outcome']} | {row['seconds']:.2f} | {ratio} | {row['newton']} | {row['krylov']} | "
                      f"{row['builds']} | {row['said']} |", flush=True)
    print(f"load average after: {' '.join(open('/proc/loadavg').read().split()[:3])}")


if __name__ == "__main__":
    main()
