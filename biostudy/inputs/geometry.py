"""Shapes of a scene (box, sphere, cylinder, mask, an image: `images`; for obstacles also the
generated maze and grate of paper 4.4 and 4.5) and the cells they cover.

A cell belongs to a shape when its centre is inside (boundaries included).
Coordinates are physical (µm) with the origin at the grid's corner, listed
x, y[, z]: two entries in a 2-D scene, where a sphere is a disc and a
cylinder along z is a disc too (along x or y it is a band of width
2 radius and the given length).

`cells(grid)` returns a boolean array in the solver's cell order,
``grid.cells_shape`` = (nz, ny, nx) / (ny, nx).  A `mask` file is the
exception a user writes in scene order: a ``.npy`` boolean array of shape
[nx, ny(, nz)] (index [i, j, k] is the cell at x_i, y_j, z_k), transposed here.

`distance(grid)` is the signed distance to the surface (negative inside):
exact for box, sphere and cylinder, from the rasterised cells otherwise.
It gives initial biofilm regions a smooth edge (`edge` in the scene).
"""
from __future__ import annotations

import functools
import math
import os
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from solver import Grid
from solver.problem import Face, face_problem

from ..errors import BadInput, InvalidAt, first_line
from ..formatting import value_text
from . import structures
from .files import MASK_BYTES, checked

Point = Annotated[list[float], Field(min_length=2, max_length=3)]
EPS = 1e-9  # relative tolerance of "inside" (cell centres on a boundary count as inside)


def um(description: str, **kw):
    """A length field (µm): unit recorded for docs and study coordinates."""
    return Field(description=description, json_schema_extra={"units": "um"}, **kw)


class Shape(BaseModel):
    """A region of space; subclasses say which cells it covers."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    def cells(self, grid: Grid) -> np.ndarray:
        """Boolean array of ``grid.cells_shape``: cells whose centre is inside."""
        raise NotImplementedError

    def points(self) -> dict[str, list[float]]:
        """Named coordinate lists, checked against the grid's dimension and extent."""
        return {}

    def distance(self, grid: Grid) -> np.ndarray:
        """Signed distance (µm) of each cell centre to the shape's surface, negative inside."""
        inside = self.cells(grid)  # from the rasterised shape: accurate to about a cell
        from scipy.ndimage import distance_transform_edt

        h = grid.spacing
        return (distance_transform_edt(~inside) - distance_transform_edt(inside)) * h + np.where(inside, 0.5, -0.5) * h

    def check(self, grid: Grid) -> None:
        """Raise `InvalidAt` if the shape does not fit the grid or covers no cell."""
        for name, point in self.points().items():
            if len(point) != grid.ndim:
                raise InvalidAt(name, f"has {len(point)} coordinates; the grid is {grid.ndim}-D")
            tol = EPS * grid.spacing
            for axis, value, top in zip(grid.axes, point, grid.extent):
                if not -tol <= value <= top + tol:
                    raise InvalidAt(name, f"{axis} = {value:g} µm lies outside the grid [0, {top:g}] µm")
        if not self.cells(grid).any():
            raise InvalidAt("", "contains no cell centre (cells belong to a shape when their centre is inside)")


def _from_gaps(gaps: list[np.ndarray]) -> np.ndarray:
    """Signed distance to an intersection of slabs, each given by its signed gap (> 0 outside):
    the Euclidean length of the positive gaps outside, the largest gap inside."""
    outside = np.sqrt(sum(np.maximum(g, 0.0) ** 2 for g in gaps))
    return outside + np.minimum(np.maximum.reduce(gaps), 0.0)


class Box(Shape):
    """Axis-aligned box between two corners."""

    shape: Literal["box"] = Field(description="box: cells with lower <= centre <= upper")
    lower: Point = um("lower corner x, y[, z], µm")
    upper: Point = um("upper corner x, y[, z], µm")

    @model_validator(mode="after")
    def _ordered(self):
        if len(self.lower) != len(self.upper):
            raise InvalidAt("upper", f"has {len(self.upper)} coordinates, lower has {len(self.lower)}")
        for axis, low, high in zip("xyz", self.lower, self.upper):
            if not low < high:
                raise InvalidAt("upper", f"{axis}: upper ({high:g}) must be greater than lower ({low:g})")
        return self

    def points(self):
        return {"lower": self.lower, "upper": self.upper}

    def cells(self, grid):
        tol = EPS * grid.spacing
        inside = np.ones(grid.cells_shape, bool)
        for q, low, high in zip(grid.cell_coordinates(), self.lower, self.upper):
            inside &= (q >= low - tol) & (q <= high + tol)
        return inside

    def distance(self, grid):
        return _from_gaps([np.maximum(low - q, q - high)
                           for q, low, high in zip(grid.cell_coordinates(), self.lower, self.upper)])


class Sphere(Shape):
    """Ball (3-D) or disc (2-D)."""

    shape: Literal["sphere"] = Field(description="sphere (3-D) or disc (2-D)")
    center: Point = um("centre x, y[, z], µm; must lie in the grid")
    radius: float = um("radius, µm", gt=0)

    def points(self):
        return {"center": self.center}

    def cells(self, grid):
        squared = sum((q - c) ** 2 for q, c in zip(grid.cell_coordinates(), self.center))
        return squared <= self.radius**2 * (1 + EPS)

    def distance(self, grid):
        return np.sqrt(sum((q - c) ** 2 for q, c in zip(grid.cell_coordinates(), self.center))) - self.radius


class Cylinder(Shape):
    """Circular cylinder along a coordinate axis, centred at `center`."""

    shape: Literal["cylinder"] = Field(description="circular cylinder along x, y or z")
    center: Point = um("centre of the axis segment x, y[, z], µm; must lie in the grid")
    radius: float = um("radius, µm", gt=0)
    axis: Literal["x", "y", "z"] = Field("z", description="direction of the cylinder's axis")
    length: float | None = um("length along the axis, µm (may reach beyond the grid); absent: unbounded",
                              default=None, gt=0)

    def points(self):
        return {"center": self.center}

    def check(self, grid):
        if grid.ndim == 2 and self.axis == "z" and len(self.center) == 2:
            pass  # a cylinder along z cut by the 2-D plane: a disc
        elif "xyz".index(self.axis) >= grid.ndim:
            raise InvalidAt("axis", f"'{self.axis}' is not an axis of a {grid.ndim}-D grid")
        super().check(grid)

    def cells(self, grid):
        coords = grid.cell_coordinates()
        along = "xyz".index(self.axis)
        tol = EPS * grid.spacing
        radial = sum((q - c) ** 2 for i, (q, c) in enumerate(zip(coords, self.center)) if i != along)
        inside = radial <= self.radius**2 * (1 + EPS)
        if along < grid.ndim and self.length is not None:
            inside &= np.abs(coords[along] - self.center[along]) <= 0.5 * self.length + tol
        return inside

    def distance(self, grid):
        coords = grid.cell_coordinates()
        along = "xyz".index(self.axis)
        radial = np.sqrt(sum((q - c) ** 2 for i, (q, c) in enumerate(zip(coords, self.center)) if i != along))
        gaps = [radial - self.radius]
        if along < grid.ndim and self.length is not None:
            gaps.append(np.abs(coords[along] - self.center[along]) - 0.5 * self.length)
        return _from_gaps(gaps)


def input_path(value: str, info: ValidationInfo, what: str, kind: str) -> str:
    """A file a scene reads (mask, image), resolved: a relative path is relative to the scene file and must stay
    inside its folder (no ../), an absolute one (or ~/...) is taken as given; it must be a regular file of at
    most `files.MASK_BYTES` (`files.checked`; `kind` names it there, e.g. "a .npy mask file")."""
    base = Path((info.context or {}).get("base", "."))
    given = Path(value).expanduser()
    if not given.is_absolute() and os.path.normpath(given).split(os.sep)[0] == os.pardir:
        raise ValueError(f"{what} {value!r} lies outside the scene's folder {base}; a relative path must "
                         "stay inside it (give an absolute path to read a file elsewhere)")
    path = base / given
    if not path.exists():
        raise ValueError(f"{what} {value!r} not found (looked for {path})")
    try:
        checked(path, MASK_BYTES, kind)
    except BadInput as error:
        where = "" if str(path) == value else f" ({path})"
        raise ValueError(f"{what} {value!r}{where} {error.problem}") from None
    return str(path.resolve())


class Mask(Shape):
    """Cells given by a boolean .npy array of the grid's shape [nx, ny(, nz)]."""

    shape: Literal["mask"] = Field(description="cells listed in a .npy file")
    path: str = Field(description="path to a .npy boolean array of shape [nx, ny(, nz)] (index [i, j, k] is the "
                                  "cell at x_i, y_j, z_k); a relative path is relative to the scene file and stays "
                                  "inside its folder, an absolute one (or ~/...) is taken as given")
    _array: np.ndarray = PrivateAttr()

    @field_validator("path")
    @classmethod
    def _resolve(cls, value: str, info: ValidationInfo) -> str:
        return input_path(value, info, "mask file", "a .npy mask file")

    @model_validator(mode="after")
    def _load(self):
        stat = Path(self.path).stat()
        self._array = _read_mask(self.path, stat.st_mtime_ns, stat.st_size)
        return self

    def check(self, grid):
        if self._array.shape != grid.shape:
            raise InvalidAt("path", f"array has shape {value_text(list(self._array.shape))}; the grid is "
                                    f"{value_text(list(grid.shape))} [nx, ny(, nz)]")
        super().check(grid)

    def cells(self, grid):
        return np.ascontiguousarray(self._array.T)  # [x, y, z] -> (z, y, x)


@functools.lru_cache(maxsize=8)
def _read_mask(path: str, mtime_ns: int, size: int) -> np.ndarray:
    """A mask file as a read-only boolean array, read once however many study cases use it.  The header is
    checked against the file's size before the data are read (a crafted header cannot ask for memory)."""
    try:
        with open(path, "rb") as handle:
            version = np.lib.format.read_magic(handle)
            read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) \
                else np.lib.format.read_array_header_2_0
            shape, _, dtype = read_header(handle)
            data_bytes = os.fstat(handle.fileno()).st_size - handle.tell()
    except OSError as error:
        raise InvalidAt("path", f"cannot read {path} ({error.strerror or error})") from None
    except Exception as error:  # whatever a damaged or crafted header raises (ValueError, SyntaxError, ...)
        reason = first_line(error)
        raise InvalidAt("path", f"cannot read {path} as a .npy array: not a .npy file ({reason})") from None
    if dtype.hasobject:
        raise InvalidAt("path", f"cannot read {path} as a .npy array: it holds Python objects, not booleans")
    if math.prod(shape) * dtype.itemsize != data_bytes:
        raise InvalidAt("path", f"cannot read {path} as a .npy array: its header announces {value_text(list(shape))} "
                                f"{dtype} values, but the file holds {data_bytes} bytes of data")
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise InvalidAt("path", f"cannot read {path} as a .npy array ({first_line(error)})") from None
    if array.dtype != bool:
        if not (np.issubdtype(array.dtype, np.integer) and np.isin(array, (0, 1)).all()):
            raise InvalidAt("path", f"{path} holds {array.dtype} values; a mask is boolean (or 0/1)")
        array = array.astype(bool)
    array.flags.writeable = False
    return array


class Maze(Shape):
    """The walls of a seeded circular maze (paper 4.4), generated by `structures.CircularMaze`;
    in a 3-D grid extruded along z."""

    shape: Literal["maze"] = Field(description="walls of a generated circular maze (same seed, same maze)")
    center: Point = um("centre x, y[, z] of the maze, µm (z is ignored: walls run along z)")
    diameter: float = um("outer diameter, µm (outside it everything is wall)", gt=0)
    wall: float = um("wall thickness, µm", gt=0)
    rings: int = Field(description="ring corridors between the central circle and the outer wall", ge=1, le=50)
    core_radius: float = um("radius of the open central circle, µm", gt=0)
    seed: int = Field(0, description="random seed of the layout", ge=0)
    entrance_angle: float = Field(0.0, description="direction of the entrance in the outer wall, degrees "
                                                   "counter-clockwise from +x", json_schema_extra={"units": "degree"})

    @model_validator(mode="after")
    def _fits(self):
        corridor = (0.5 * self.diameter - self.wall - self.core_radius) / self.rings - self.wall
        if corridor <= 0:
            raise InvalidAt("rings", f"{self.rings} rings of {self.wall:g} µm walls do not fit between the core "
                                     f"(radius {self.core_radius:g} µm) and the outer wall "
                                     f"(diameter {self.diameter:g} µm)")
        return self

    def layout(self) -> structures.CircularMaze:
        return structures.CircularMaze(center=tuple(self.center[:2]), diameter=self.diameter, wall=self.wall,
                                       rings=self.rings, core_radius=self.core_radius, seed=self.seed,
                                       entrance_angle=np.deg2rad(self.entrance_angle))

    def points(self):
        return {"center": self.center}

    def cells(self, grid):
        x, y = grid.cell_coordinates()[:2]
        return self.layout().walls(x, y)


class Grate(Shape):
    """Square bars on a square lattice filling a box (paper 4.5); in a 3-D grid, columns along z."""

    shape: Literal["grate"] = Field(description="square bars on a square lattice inside a box")
    lower: Point = um("lower corner x, y[, z] of the box the bars fill, µm (z ignored)")
    upper: Point = um("upper corner x, y[, z], µm")
    bar: float = um("side of a bar, µm", gt=0)
    pitch: float = um("distance between neighbouring bars' centres, µm", gt=0)

    @model_validator(mode="after")
    def _fits(self):
        if len(self.lower) != len(self.upper):
            raise InvalidAt("upper", f"has {len(self.upper)} coordinates, lower has {len(self.lower)}")
        if self.pitch <= self.bar:
            raise InvalidAt("pitch", f"{self.pitch:g} µm leaves no gap between bars of {self.bar:g} µm")
        for axis, low, high in zip("xy", self.lower, self.upper):
            if high - low < self.bar:
                raise InvalidAt("upper", f"{axis}: the box ({high - low:g} µm) is narrower than a bar")
        return self

    def points(self):
        return {"lower": self.lower, "upper": self.upper}

    def cells(self, grid):
        x, y = grid.cell_coordinates()[:2]
        return structures.grate(x, y, self.lower[:2], self.upper[:2], self.bar, self.pitch)


class BoundaryFace(Shape):
    """An outer face of the grid: for a nutrient source held on the face itself (the paper's nodes on the
    bottom plane), a Dirichlet condition half a cell from the cells beside it, which stay free."""

    shape: Literal["face"] = Field(description="an outer face of the grid (nutrient sources only)")
    face: Face = Field(description="which face: x-, x+, y-, y+, z-, z+")

    def check(self, grid):
        problem = face_problem(self.face, grid.ndim)
        if problem:
            raise InvalidAt("face", problem)

    def cells(self, grid):
        return np.zeros(grid.cells_shape, bool)  # no cell is held: the face is


SHAPES = (Box, Sphere, Cylinder, Mask)  # drawn shapes and masks (the scene adds images: `scene.SHAPES`)
