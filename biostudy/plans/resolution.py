"""Whether a grid resolves a scene: its regions' volumes on that grid against another.

A region of a scene (biofilm, held nutrient, obstacle) becomes the cells whose
centres lie inside it (`inputs.geometry`), so its volume on a grid depends on
the cell size.  On a grid too coarse for it the region is another one: the
directional scene's corner source is one 1 µm cell (1 µm³) on 1 µm cells and
one 2 µm cell (8 µm³) on 2 µm cells; the agar2d colony, 6 µm wide, covers
24 µm² on 1 µm cells and 32 µm² on 2 µm cells.  A run on such a grid solves a
different model, and a difference between it and a finer run is not a
discretisation error: refinement levels and error-estimate companions whose
regions change volume by more than `FRACTION` against the grid they are
compared with, or cover no cell at all, are flagged as a different model.

`FRACTION` is a quarter: each face of a box moves by at most half a cell when
it is rasterised, so a region at least 4 cells across changes its volume by at
most 2 x 1/2 / 4 = 25 % along any axis; a region thinner than that is not
resolved.  Faces (nutrient held on a boundary face) have no volume and are
resolved on every grid.  A biofilm region that is at least `LAYERS` cells
thick on the grid compared with and thinner on the other (along an axis it does
not span whole) is not resolved either, whatever its volume: a colony one cell
thick has no inside, its front and its interior are the same cells (the agar
colony, 5 µm across, is 8 cells of 2 µm and one of 4 µm, 64 µm³ on both).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..inputs.geometry import BoundaryFace
from ..inputs.keys import set_key
from ..inputs.scene import Scene, scene_from_data

FRACTION = 0.25
LAYERS = 2
KINDS = ("biofilm", "nutrient", "obstacle")


def region_volumes(scene: Scene) -> dict[str, float]:
    """{"biofilm[0]": volume, ...}: each region's rasterised volume on the scene's grid (µm³; 2-D: µm² per µm)."""
    grid = scene.grid.solver_grid()
    out = {}
    for kind in KINDS:
        for i, region in enumerate(getattr(scene, kind)):
            if isinstance(region, BoundaryFace):
                continue
            out[f"{kind}[{i}]"] = float(region.cells(grid).sum()) * grid.cell_volume
    return out


def thickness(scene: Scene) -> dict[str, dict[str, int]]:
    """{"biofilm[0]": {"x": cells, ...}}: each biofilm region's extent in cells along each axis it does not span
    whole (its bounding box)."""
    grid = scene.grid.solver_grid()
    out = {}
    for i, region in enumerate(scene.biofilm):
        cells = region.cells(grid)
        extents = {}
        for axis, name in enumerate(reversed(grid.axes)):  # cells are (z, y, x)
            found = np.flatnonzero(cells.any(axis=tuple(a for a in range(cells.ndim) if a != axis)))
            if found.size and found.size < cells.shape[axis]:
                extents[name] = int(found[-1] - found[0] + 1)
        out[f"biofilm[{i}]"] = extents
    return out


def differences(scene: Scene, against: Scene) -> list[str]:
    """A sentence for each region whose volume on `scene`'s grid differs from that on `against`'s by more than
    `FRACTION` (or which covers no cell), and each biofilm region thinner than `LAYERS` cells there but not on
    `against`'s grid; [] when the grid resolves every region as `against`'s does."""
    mine, theirs = region_volumes(scene), region_volumes(against)
    h, other = scene.grid.spacing, against.grid.spacing
    unit = "µm³" if len(scene.grid.shape) == 3 else "µm²"
    found = []
    for name, volume in mine.items():
        wanted = theirs[name]
        if wanted > 0 and abs(volume - wanted) <= FRACTION * wanted:
            continue
        found.append(f"{name} covers {volume:g} {unit} on {h:g} µm cells against {wanted:g} {unit} on {other:g} µm "
                     f"cells")
    theirs_thick = thickness(against)
    for name, extents in thickness(scene).items():
        thin = [axis for axis, cells in extents.items() if cells < LAYERS <= theirs_thick[name].get(axis, LAYERS)]
        if thin:
            before = ", ".join(str(theirs_thick[name][axis]) for axis in thin)
            found.append(f"{name} is 1 cell thick along {', '.join(thin)} on {h:g} µm cells ({before} on {other:g} µm "
                         "cells): it has no inside")
    return found


def regridded(scene: Scene, file: str | Path, shape: list[int], spacing: float, steps: int | None = None,
              tolerance: float | None = None) -> Scene:
    """The same scene on another grid (and step count, or error tolerance): validated as a scene file would be.
    A region that covers no cell there, or a mask of fixed resolution, is `BadInput`."""
    for kind in KINDS:
        for i, region in enumerate(getattr(scene, kind)):
            if getattr(region, "shape", None) == "mask" and list(shape) != list(scene.grid.shape):
                raise BadInput("a mask has the resolution of its file and cannot be put on another grid", file,
                               f"{kind}[{i}]")
    data = scene.model_dump(mode="json", exclude_none=True)
    set_key(data, "grid.shape", [int(n) for n in shape])
    set_key(data, "grid.spacing", float(spacing))
    if steps is not None:
        set_key(data, "time.steps", int(steps))
    if tolerance is not None:
        set_key(data, "numerics.time_tolerance", float(tolerance))
    return scene_from_data(data, file)


def resolves_like(scene: Scene, file: str | Path, finest: Scene):
    """A test of a grid (shape, spacing) of `scene`'s domain: True if it holds every region as `finest` does
    (`differences`), False if it does not or cannot hold one at all."""
    def test(shape: list[int], spacing: float) -> bool:
        try:
            return not differences(regridded(scene, file, shape, spacing), finest)
        except BadInput:
            return False

    return test
