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
resolved on every grid.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import BadInput
from ..inputs.geometry import BoundaryFace
from ..inputs.keys import set_key
from ..inputs.scene import Scene, scene_from_data

FRACTION = 0.25
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


def differences(scene: Scene, against: Scene) -> list[str]:
    """A sentence for each region whose volume on `scene`'s grid differs from that on `against`'s by more than
    `FRACTION` (or which covers no cell); [] when the grid resolves every region as `against`'s does."""
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
