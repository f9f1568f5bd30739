"""Observed order of the hydrostatic stress p under mesh refinement: a growing dense sphere (paper section 3).

    python benchmarks/mechanics_order.py
    python benchmarks/mechanics_order.py --sizes 6 12 24 48 96    # a fifth level (~8 GB, minutes)

One octant of a 16 µm cube (slide on the symmetry planes x-, y-, z-), a
sphere of radius 4 µm with a smooth edge (tanh, width 1 µm), alpha = 0.01 phi,
Table 2 parameters, Newton tolerance 1e-8.  Q = Gaussian-weighted mean of p near the centre on
h = 4/3, 2/3, 1/3, 1/6 µm, for both pressures a dataset can hold (from the same
solve): Q1/P0's element pressure and the recovered one (solver/mechanics/pressure.py).
The observed order from successive differences, log2(|Q_h - Q_h/2| / |Q_h/2 - Q_h/4|),
and the Richardson estimate of the limit.  Prints a table for docs/mechanics.md.
"""
import argparse
import os
import time

import numpy as np

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import GrowthMechanics, material

L, A = 8.0, 4.0


def quantities(n: int) -> tuple[dict, float, tuple[float, float]]:
    grid = Grid((n, n, n), L / n)
    x, y, z = grid.cell_coordinates()
    r = np.sqrt(x**2 + y**2 + z**2)
    phi = 0.5 * (1 - np.tanh(r - A))
    setup = MechanicsSetup(slide=("x-", "y-", "z-"), newton_tolerance=1e-8, pressure="element")
    began, cpu = time.perf_counter(), time.process_time()
    mechanics = GrowthMechanics(grid, Parameters(), setup)
    element = mechanics.solve(phi, 0.01 * phi, 1.0).p.ravel()
    seconds = (time.perf_counter() - began, time.process_time() - cpu)
    recovered = mechanics.pressure.recover(element[mechanics.mesh.cells],
                                           material.weight(phi.ravel(), setup.residual_stiffness))
    weight = np.exp(-(r.ravel() / 2) ** 2)
    Q = {name: float((p * weight).sum() / weight.sum()) for name, p in (("element", element), ("recovered", recovered))}
    return Q, float(element.min()), seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[6, 12, 24, 48], help="cells per octant edge")
    sizes = parser.parse_args().sizes
    print(f"load average {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores); solve: wall and CPU seconds")
    names = ("element", "recovered")
    print(f"{'cells':>6} {'h um':>6} " + " ".join(f"{'Q ' + n + ' Pa':>16} {'|dQ|':>9} {'order':>6}" for n in names)
          + f" {'solve s':>8} {'cpu s':>6}")
    series = {name: [] for name in names}
    for n in sizes:
        Q, _, seconds = quantities(n)
        cells = []
        for name in names:
            q = series[name]
            q.append(Q[name])
            diff = abs(q[-1] - q[-2]) if len(q) > 1 else float("nan")
            order = np.log2(abs(q[-3] - q[-2]) / diff) if len(q) > 2 else float("nan")
            cells.append(f"{q[-1]:>16.7f} {diff:>9.2e} {order:>6.2f}")
        print(f"{n:>4}^3 {L / n:>6.3f} " + " ".join(cells) + f" {seconds[0]:>8.2f} {seconds[1]:>6.2f}", flush=True)
    for name in names:
        q = series[name]
        order = np.log2(abs(q[-3] - q[-2]) / abs(q[-2] - q[-1]))
        limit = q[-1] + (q[-1] - q[-2]) / (2**order - 1)
        errors = ", ".join(f"{abs(v - limit):.1e}" for v in q)
        print(f"{name}: Richardson limit {limit:.7f} Pa (order {order:.2f}); errors against it {errors} Pa")


if __name__ == "__main__":
    main()
