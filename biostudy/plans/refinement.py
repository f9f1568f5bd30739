"""The refinement plan of `biostudy convergence`: the levels of each series, each a scene.

Four refinement series from the scene as given (level 0):
  space     the grid refined by 2 per level (cells 2^ndim x), the time step kept;
  time      the nominal step halved per level, the grid kept;
  both      grid and step refined together;
  adaptive  error-controlled steps (step doubling) with the tolerance divided
            by 4 per level (local error ~ dt^2: halves the step), the grid kept.
Every series is measured against one reference, the Richardson extrapolation
of the two finest levels of `both` (`reports.convergence`), which the plan adds
when `both` is not asked for.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import BadInput

if TYPE_CHECKING:
    from ..inputs.scene import Scene

SERIES = ("space", "time", "both", "adaptive")
FIRST_TOLERANCE = 1e-2  # adaptive level 0: local error in phi per step


@dataclass(frozen=True)
class Refinement:
    """One level of one refinement series: how much finer than the scene as given (level 0) it is."""

    series: str
    index: int
    refine: int  # grid refinement factor against level 0
    steps: int
    tolerance: float | None

    @property
    def job_id(self) -> str:
        text = f"refine={self.refine}_steps={self.steps}"
        return text + (f"_tol={self.tolerance:.3g}" if self.tolerance is not None else "")


def plan(base: Scene, levels: int, series: tuple[str, ...] = SERIES,
         tolerance: float = FIRST_TOLERANCE, reference: bool = True) -> list[Refinement]:
    """The levels of every requested series (plus those of `both`, the `reference`, when not asked for)."""
    steps = base.time.steps
    out = []
    for name in series:
        for i in range(levels):
            if name == "space":
                out.append(Refinement(name, i, 2**i, steps, None))
            elif name == "time":
                out.append(Refinement(name, i, 1, steps * 2**i, None))
            elif name == "both":
                out.append(Refinement(name, i, 2**i, steps * 2**i, None))
            else:
                out.append(Refinement(name, i, 1, steps, tolerance / 4**i))
    if reference and "both" not in series:
        out += [Refinement("both", i, 2**i, steps * 2**i, None) for i in range(levels)]
    return out


def with_reference(series: tuple[str, ...]) -> tuple[str, ...]:
    """The series a convergence study reports: those asked for, and `both`, whose finest levels are the
    reference of all."""
    return series if "both" in series else (*series, "both")


def refined(data: dict, scene_file: Path, level: Refinement) -> Scene:
    """The base scene's data with the level's grid, steps and tolerance."""
    from ..inputs.keys import set_key  # here: `biostudy convergence -h` reads SERIES from this module, not the solver
    from ..inputs.resources import Preflight
    from ..inputs.scene import scene_from_data

    data = copy.deepcopy(data)
    grid = data["grid"]
    set_key(data, "grid.shape", [n * level.refine for n in grid["shape"]])
    set_key(data, "grid.spacing", float(grid.get("spacing", 1.0)) / level.refine)
    set_key(data, "time.steps", level.steps)
    if level.tolerance is not None:
        set_key(data, "numerics.time_tolerance", level.tolerance)
    return scene_from_data(data, scene_file, preflight=Preflight())  # validating a finer grid fits here


def check_refinable(base: Scene, scene_file: Path) -> None:
    for kind in ("biofilm", "nutrient", "obstacle"):
        for i, region in enumerate(getattr(base, kind)):
            if getattr(region, "shape", None) == "mask":
                raise BadInput("a mask region has a fixed resolution and cannot be refined; describe it by "
                               "shapes to measure convergence", scene_file, f"{kind}[{i}]")
