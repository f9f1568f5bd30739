"""Observed order of the hydrostatic stress p under mesh refinement: a growing dense sphere (paper 3).

    python benchmarks/mechanics_order.py

One octant of a 16 µm cube (slide on the symmetry planes x-, y-, z-), a
sphere of radius 4 µm with a smooth edge (tanh, width 1 µm), alpha = 0.01 phi,
Table 2 parameters, Newton tolerance 1e-8.  Q = Gaussian-weighted mean of p near the centre on
h = 4/3, 2/3, 1/3, 1/6 µm; the observed order from successive differences,
log2(|Q_h - Q_h/2| / |Q_h/2 - Q_h/4|), and the Richardson estimate of the
limit.  Prints a table for docs/mechanics.md.
"""
import time

import numpy as np

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import GrowthMechanics

L, A = 8.0, 4.0


def quantity(n: int) -> tuple[float, float, float]:
    grid = Grid((n, n, n), L / n)
    x, y, z = grid.cell_coordinates()
    r = np.sqrt(x**2 + y**2 + z**2)
    phi = 0.5 * (1 - np.tanh(r - A))
    began = time.perf_counter()
    p = GrowthMechanics(grid, Parameters(), MechanicsSetup(slide=("x-", "y-", "z-"), newton_tolerance=1e-8)).solve(phi, 0.01 * phi, 1.0).p
    weight = np.exp(-(r / 2) ** 2)
    return (p * weight).sum() / weight.sum(), float(p.min()), time.perf_counter() - began


def main():
    print(f"{'cells':>6} {'h um':>6} {'Q Pa':>12} {'|dQ|':>10} {'order':>6} {'min p Pa':>10} {'solve s':>8}")
    Q, previous = [], None
    for n in (6, 12, 24, 48):
        q, pmin, seconds = quantity(n)
        Q.append(q)
        diff = abs(Q[-1] - Q[-2]) if len(Q) > 1 else float("nan")
        order = np.log2(previous / diff) if previous else float("nan")
        print(f"{n:>4}^3 {L / n:>6.3f} {q:>12.6f} {diff:>10.2e} {order:>6.2f} {pmin:>10.4f} {seconds:>8.2f}", flush=True)
        previous = diff if len(Q) > 1 else None
    order = np.log2(abs(Q[-3] - Q[-2]) / abs(Q[-2] - Q[-1]))
    limit = Q[-1] + (Q[-1] - Q[-2]) / (2**order - 1)
    print(f"Richardson limit of Q: {limit:.6f} Pa (order {order:.2f}); error of the finest level {abs(Q[-1] - limit):.2e} Pa")


if __name__ == "__main__":
    main()
