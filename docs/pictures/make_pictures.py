"""Remake the example pictures in this directory: the directional scene (paper 4.1) at 20³ cells.

    PYTHONPATH=. python docs/pictures/make_pictures.py

Builds the scene directly with the solver (phi = 1 in a sphere of radius 5 µm
at the centre, c = 1 held in the corner box x, y, z > 17 µm, Table 2
parameters, t_end = 1, 200 steps, 11 outputs), runs it, calls
`biostudy.plots.plot` with its defaults and prints both run times.
"""
import time
from pathlib import Path

import numpy as np

from biostudy.plots import plot
from solver import Grid, Problem, simulate

HERE = Path(__file__).parent


def directional() -> Problem:
    grid = Grid((20, 20, 20), 1.0)
    x, y, z = grid.cell_coordinates()
    sphere = (x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 5**2
    corner = (x > 17) & (y > 17) & (z > 17)
    return Problem(grid=grid, phi0=sphere.astype(float), nutrient_fixed=corner, t_end=1.0, steps=200,
                   output_times=np.linspace(0, 1, 11), name="directional")


if __name__ == "__main__":
    began = time.perf_counter()
    ds = simulate(directional())
    simulated = time.perf_counter()
    paths = plot(ds, HERE / "directional.png")
    drawn = time.perf_counter()
    print(f"simulate {simulated - began:.1f} s, plot {drawn - simulated:.1f} s")
    for path in paths:
        print(f"  {path.name} ({path.stat().st_size // 1024} KiB)")
