"""The two pressures a dataset can hold, measured: spurious modes, exact answers, cost. Prints tables.

    python benchmarks/mechanics_pressure.py            # all three parts (the grate run takes a minute)
    python benchmarks/mechanics_pressure.py --skip-grate

1. Checkerboard.  Per interior node, over its 2 x 2 cells a, b, c, d (2-D
   rows and columns): the checkerboard |p_a - p_b - p_c + p_d| / 4 against
   the smooth part |p_a + p_b + p_c + p_d| / 4; the largest of each, over all
   nodes and over the nodes more than 3 cells from every corner of the
   domain and of the obstacles.  Cases: a dense block of 40 x 40 µm (plane
   strain) clamped on y-, a rigid 8 µm square in its middle, alpha = 0.01
   (k_alpha = 1e-2, T* = 1), on 20^2, 40^2, 80^2 cells; and the bundled grate
   scene at T* = 4 (its own run, mechanics at the end).  Both pressures come
   from the same solve.  Also the largest change of the smooth part.
2. Exact answers, both pressures: all faces clamped around an obstacle,
   p = kappa((1 + alpha)^-3 - 1); a free dense block, p = 0 (alpha = 0.05,
   Newton tolerance 1e-13).
3. Cost of the recovery per snapshot against the snapshot itself.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from solver import Grid, MechanicsSetup, Parameters
from solver.mechanics import GrowthMechanics, material

PARAMS = Parameters()


def both(mechanics: GrowthMechanics, phi_cells: np.ndarray) -> dict:
    """Element and recovered pressure of the mechanics' last equilibrium, as grid arrays."""
    phi = phi_cells.ravel()[mechanics.mesh.cells]
    element = mechanics._evaluator(phi, mechanics.alpha)(mechanics.u, False).pressure
    recovered = mechanics.pressure.recover(element, material.weight(phi, mechanics.setup.residual_stiffness))
    out = {}
    for name, values in (("element", element), ("recovered", recovered)):
        full = np.full(mechanics.grid.n_cells, np.nan)
        full[mechanics.mesh.cells] = values
        out[name] = full.reshape(mechanics.grid.cells_shape)
    return out


def checkerboard(p: np.ndarray, grid: Grid, corners, away: float = 3) -> dict:
    a, b, c, d = p[:-1, :-1], p[:-1, 1:], p[1:, :-1], p[1:, 1:]
    checker, smooth = np.abs(a - b - c + d) / 4, (a + b + c + d) / 4
    h = grid.spacing
    ny, nx = grid.cells_shape
    y, x = np.meshgrid(np.arange(1, ny) * h, np.arange(1, nx) * h, indexing="ij")
    distance = np.min([np.maximum(abs(x - cx), abs(y - cy)) for cx, cy in corners], axis=0)
    valid = np.isfinite(checker)
    far = valid & (distance > away * h)
    return {"all": (checker[valid].max(), np.abs(smooth[valid]).max()),
            "far": (checker[far].max(), np.abs(smooth[far]).max()), "smooth": smooth, "far_mask": far}


def obstacle_corners(obstacle: np.ndarray, h: float):
    """Grid points that are corners of the obstacle (an odd number of its 4 cells around them is solid)."""
    padded = np.pad(obstacle, 1).astype(int)
    count = padded[:-1, :-1] + padded[:-1, 1:] + padded[1:, :-1] + padded[1:, 1:]
    j, i = np.nonzero(count % 2 == 1)
    return list(zip(i * h, j * h))


def print_rows(label: str, grid: Grid, fields: dict, corners):
    measured = {name: checkerboard(p, grid, corners) for name, p in fields.items()}
    for name, m in measured.items():
        (c_all, s_all), (c_far, s_far) = m["all"], m["far"]
        print(f"{label:<14} {name:<10} {c_all:>10.3g} {s_all:>10.3g} {100 * c_all / s_all:>6.1f} % "
              f"{c_far:>10.3g} {s_far:>10.3g} {100 * c_far / s_far:>6.1f} %")
    far = measured["element"]["far_mask"]
    change = np.abs(measured["recovered"]["smooth"] - measured["element"]["smooth"])[far].max()
    print(f"{'':<14} smooth part changed by at most {change:.3g} Pa away from corners "
          f"({100 * change / measured['element']['far'][1]:.2f} %)")


def block(n: int):
    grid = Grid((n, n), 40.0 / n)
    x, y = grid.cell_coordinates()
    obstacle = (x > 16) & (x < 24) & (y > 16) & (y < 24)
    corners = [(0, 0), (40, 0), (0, 40), (40, 40), (16, 16), (16, 24), (24, 16), (24, 24)]
    phi = np.where(obstacle, 0.0, 1.0)
    mechanics = GrowthMechanics(grid, PARAMS, MechanicsSetup(clamp=("y-",)), obstacle)
    mechanics.solve(phi, np.where(obstacle, 0.0, 0.01), 1.0)
    print_rows(f"block {n}^2", grid, both(mechanics, phi), corners)


def grate():
    from biostudy.inputs import bundled
    from biostudy.inputs.scene import load_scene
    from solver import Simulation

    scene = load_scene(bundled.resolve("grate"), ["mechanics.every=1000"])
    problem = scene.problem()
    run = Simulation(problem)
    *_, last = list(run)
    grid = problem.grid
    corners = obstacle_corners(problem.obstacle, grid.spacing) + [(0, 0), (grid.extent[0], 0), (0, grid.extent[1]),
                                                                  grid.extent]
    print_rows(f"grate T*={last.time:g}", grid, both(run.mechanics, np.nan_to_num(last.phi)), corners)


def exact():
    print(f"{'case':<32} {'pressure':<10} {'max error':>10}")
    alpha = 0.05
    for name in ("element", "recovered"):
        grid = Grid((6, 5, 4), 1.0)
        obstacle = np.zeros(grid.cells_shape, bool)
        obstacle[1:3, 1:3, 1:3] = True
        setup = MechanicsSetup(clamp=("x-", "x+", "y-", "y+", "z-", "z+"), newton_tolerance=1e-13, pressure=name)
        p = GrowthMechanics(grid, PARAMS, setup, obstacle).solve(np.where(obstacle, 0, 1.0),
                                                                 np.where(obstacle, 0, alpha), 1.0).p
        exact_p = PARAMS.kappa * ((1 + alpha) ** -3 - 1)
        print(f"{'clamped around an obstacle':<32} {name:<10} {np.nanmax(np.abs(p / exact_p - 1)):>10.1e} (relative)")
        free = GrowthMechanics(Grid((6, 5, 4), 1.0), PARAMS, MechanicsSetup(newton_tolerance=1e-13, pressure=name))
        p = free.solve(np.ones((4, 5, 6)), np.full((4, 5, 6), alpha), 1.0).p
        print(f"{'free dense block':<32} {name:<10} {np.abs(p).max():>10.1e} Pa")


def cost():
    print(f"{'cells':>6} {'recovery ms':>12} {'cpu ms':>7}")
    rng = np.random.default_rng(0)
    for n in (20, 40, 60):
        mechanics = GrowthMechanics(Grid((n, n, n), 20.0 / n), PARAMS, MechanicsSetup())
        p, w = rng.standard_normal(mechanics.mesh.n_elements), rng.uniform(1e-4, 1, mechanics.mesh.n_elements)
        began, cpu = time.perf_counter(), time.process_time()
        for _ in range(5):
            mechanics.pressure.recover(p, w)
        wall, cpu = time.perf_counter() - began, time.process_time() - cpu
        print(f"{n:>4}^3 {1e3 * wall / 5:>12.1f} {1e3 * cpu / 5:>7.1f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--skip-grate", action="store_true")
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)")
    print(f"{'case':<14} {'pressure':<10} {'checker':>10} {'smooth':>10} {'ratio':>8} "
          f"{'far: chk':>10} {'smooth':>10} {'ratio':>8}   (Pa; far = more than 3 cells from every corner)")
    for n in (20, 40, 80):
        block(n)
    if not args.skip_grate:
        grate()
    print()
    exact()
    print()
    cost()


if __name__ == "__main__":
    main()
