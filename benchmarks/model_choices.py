"""Two of the model's departures from the paper, measured (docs/model.md): prints what it finds.

1. A nutrient source that is one cell (the paper's "corner node") against a
   physical region (a 3 µm corner box), directional scene at T* = 0, grid
   refined: the single cell's supply vanishes with the cell.
2. The paper's zero-order consumption d lap(c) = g phi taken literally (no
   constraint c >= 0) on the same scene at T* = 0: how far below 0 c goes.

    python benchmarks/model_choices.py          # ~1 minute on 2 cores
"""
from __future__ import annotations

import os

os.environ.setdefault("FIPY_SOLVERS", "scipy")

import numpy as np  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

from solver import Grid, Parameters  # noqa: E402
from solver.transport.finite_volume import FiniteVolumeGrid  # noqa: E402
from solver.transport.nutrient import Nutrient  # noqa: E402


def directional(n: int):
    """Grid of n^3 cells over the 20 µm cube, the 5 µm biofilm sphere, and the two kinds of source."""
    h = 20.0 / n
    grid = Grid((n, n, n), h)
    x, y, z = grid.cell_coordinates()
    phi = ((x - 10) ** 2 + (y - 10) ** 2 + (z - 10) ** 2 <= 25).astype(float)
    one_cell = (x > 20 - h) & (y > 20 - h) & (z > 20 - h)
    box = (x > 17) & (y > 17) & (z > 17)
    return grid, phi, one_cell, box


def main() -> None:
    print("1. mean c at T* = 0, first-order consumption, Table 2 parameters")
    for n in (20, 40, 80):
        grid, phi, one_cell, box = directional(n)
        fv = FiniteVolumeGrid(grid)
        means = [Nutrient(fv, Parameters(), "first-order", held, np.ones(grid.cells_shape))
                 .solve(fv.to_active(phi)).mean() for held in (one_cell, box)]
        print(f"   h = {grid.spacing:g} µm: one corner cell held {means[0]:.4f}, 3 µm corner box held {means[1]:.4f}")
    print("2. zero-order consumption taken literally (no c >= 0), 20^3, 3 µm corner box held")
    grid, phi, _, box = directional(20)
    fv = FiniteVolumeGrid(grid)
    for g in (1e8, 1e10):
        nutrient = Nutrient(fv, Parameters(g=g), "zero-order", box, np.ones(grid.cells_shape))
        free = nutrient.c_held.copy()
        demand = nutrient.gamma * fv.to_active(phi)[nutrient.free]
        free[nutrient.free] = spla.spsolve(nutrient.stiffness.tocsc(), nutrient.rhs - demand)
        print(f"   g = {g:g}: mean c {free.mean():.4g}, smallest c {free.min():.4g}")


if __name__ == "__main__":
    main()
