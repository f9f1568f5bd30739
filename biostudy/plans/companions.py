"""The companion runs of an error estimate: the same scene on coarser cells and with longer steps.

A run at (h, dt) gets its error from three cheaper runs of the same scene
(docs/accuracy.md, "Error bars on a run"):

  coarse     (2h, 2dt)  space and time together: 1/8 of the run's cell-steps in 2-D, 1/16 in 3-D
  slow       (2h, 4dt)  with `coarse`, the time error alone (same grid): 1/16, 1/32
  coarser    (4h, 4dt)  with both, the observed spatial order: 1/64, 1/256

Together the companions take as many steps as the run (1/2 + 1/4 + 1/4): on a
small grid, where a step's fixed cost dominates, that is what they cost.

`coarse` is needed; without `slow` there is no time estimate, without
`coarser` the spatial order is assumed.  A companion is left out, with the
reason, where it cannot be made (a grid that does not halve, a region that
covers no cell, a mask) or where the coarser grid does not resolve the scene's
regions as the run's grid does (`resolution.differences`): it would solve a
different model.  Error-controlled steps (`numerics.time_tolerance`) take 4x
the tolerance for 2x the step (local error ~ dt^2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput
from ..inputs.scene import Scene
from . import resolution


@dataclass(frozen=True)
class Companion:
    """A companion run: the grid coarsened by `coarsen`, the step lengthened by `slower`."""

    name: str
    coarsen: int
    slower: int
    needed: bool
    purpose: str


COMPANIONS = (
    Companion("coarse", 2, 2, True, "space and time together"),
    Companion("slow", 2, 4, False, "the time error (with coarse)"),
    Companion("coarser", 4, 4, False, "the observed spatial order (with coarse and slow)"),
)


@dataclass(frozen=True)
class Planned:
    """A companion and its scene, or why it has none."""

    companion: Companion
    scene: Scene | None
    reason: str = ""

    def describe(self) -> str:
        """'10 x 20 cells of 2 µm, 150 steps': what the companion runs."""
        if self.scene is None:
            return f"{self.companion.name}: {self.reason}"
        grid, time = self.scene.grid, self.scene
        tolerance = time.numerics.time_tolerance
        steps = f"tolerance {tolerance:g}" if tolerance is not None else f"{time.time.steps} steps"
        return f"{self.companion.name}: {' x '.join(map(str, grid.shape))} cells of {grid.spacing:g} µm, {steps}"


def _scene(scene: Scene, file: str | Path, companion: Companion) -> Scene:
    """The companion's scene; `BadInput` saying why it cannot be made or is another model."""
    shape = scene.grid.shape
    if any(n % companion.coarsen for n in shape):
        raise BadInput(f"the grid of {' x '.join(map(str, shape))} cells does not divide by {companion.coarsen}")
    tolerance = scene.numerics.time_tolerance
    coarse = resolution.regridded(
        scene, file, [n // companion.coarsen for n in shape], scene.grid.spacing * companion.coarsen,
        steps=max(1, math.ceil(scene.time.steps / companion.slower)),
        tolerance=None if tolerance is None else tolerance * companion.slower**2)
    different = resolution.differences(coarse, scene)
    if different:
        raise BadInput("a different model: " + "; ".join(different))
    return coarse


def plan(scene: Scene, file: str | Path) -> list[Planned]:
    """Every companion of `scene`, each with its scene or the reason it has none."""
    out = []
    for companion in COMPANIONS:
        try:
            out.append(Planned(companion, _scene(scene, file, companion)))
        except BadInput as error:
            reason = f"{error.key}: {error.problem}" if error.key else error.problem
            out.append(Planned(companion, None, f"not run on {scene.grid.spacing * companion.coarsen:g} µm cells: "
                                                f"{reason}"))
    return out
