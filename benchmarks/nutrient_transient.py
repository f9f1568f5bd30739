"""The transient nutrient (`[model] nutrient = "transient"`) against the exact profile of diffusion into a
half-space held at c = 1 on its face, c = erfc(x / (2 sqrt(d t))): the error at t_end and its observed order
when the step, the cell, or both (the step as h²) are refined.

    python benchmarks/nutrient_transient.py     # a few seconds

A strip of cells (2-D, one cell wide) 16 µm long, d = 1 µm²/T*, t_end = 1 (erfc(8) ~ 1e-29 at the far face), no
biofilm; the largest error over the cells at t_end (cell centres against the exact profile).  Backward Euler is
first order in the step, the finite volumes second order in h (tests/test_laws.py checks both on a shorter
series).
"""
from __future__ import annotations

import os
import sys

import numpy as np

os.environ.setdefault("FIPY_SOLVERS", "scipy")
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "tests"))
from test_laws import erfc_error  # noqa: E402  the half-space beside its test


def error(cells: int, steps: int) -> float:
    return erfc_error(cells, steps, d=1.0, t_end=1.0)


def table(title: str, levels: list[tuple[int, int]]) -> None:
    print(f"\n{title}\n\n| cells (h µm) | steps | max error | observed order |\n|---|---|---|---|")
    previous = None
    for cells, steps in levels:
        e = error(cells, steps)
        order = "" if previous is None else f"{np.log2(previous / e):.2f}"
        print(f"| {cells} ({16 / cells:g}) | {steps} | {e:.3g} | {order} |")
        previous = e


if __name__ == "__main__":
    table("the step refined, h = 1/32 µm", [(512, s) for s in (8, 16, 32, 64, 128)])
    table("h refined, 4096 steps", [(n, 4096) for n in (16, 32, 64, 128)])
    table("both, the step as h²", [(16, 4), (32, 16), (64, 64), (128, 256)])
