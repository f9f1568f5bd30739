"""Microscopy images as scene regions (`Image`, ``shape = "image"``): a TIFF stack or a PNG/TIFF picture, read,
sized and averaged onto the grid.

The axes, said once: an image array is indexed [z, y, x] (a stack: slice,
row, column) or [y, x] (a picture: row, column), the solver's own cell order
(`solver.problem`): voxel [k, j, i] spans z in origin_z + [k, k + 1] dz,
y in origin_y + [j, j + 1] dy, x in origin_x + [i, i + 1] dx, µm.  So slice 0
lies at the bottom (z = origin_z, the substratum when a confocal stack starts
there) and row 0 at y = origin_y (ImageJ counts rows from the top of the
picture: the scene's y axis runs down it).  A scene lists points x, y, z;
`voxel` is given the image's way, [dz, dy, dx] ([dy, dx] for a picture), as
ImageJ and OME metadata state it.

Voxel sizes come from the file (ImageJ: the x and y resolution tags in pixels
per `unit` and `spacing` for z; OME: PhysicalSizeX/Y/Z with their units) or
from the scene (`voxel`, which wins).

Onto the grid: every cell takes the average of the image over the cell's
volume, each voxel weighted by how much of the cell it covers (separable
overlap weights per axis; outside the image counts as 0).  This conserves
the foreground's volume and does not depend on the cell size dividing the
voxel size; an interpolating resampler (scikit-image's `resize` with its
Gaussian anti-aliasing) would blur the foreground over cells it does not
cover.  A segmented image then covers the cells whose foreground fraction is
at least 1/2; a greyscale one does after a `threshold`, or gives phi itself
(`scale` times the cell average of the grey values).
"""
from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from solver import Grid

from ..errors import InvalidAt, first_line
from ..formatting import value_text
from .geometry import Point, Shape, input_path, um

TIFF = (".tif", ".tiff")
PICTURES = (".png", *TIFF)
MICRONS = {"um": 1.0, "\u00b5m": 1.0, "\u03bcm": 1.0, "micron": 1.0, "microns": 1.0, "micrometer": 1.0,
           "nm": 1e-3, "nanometer": 1e-3, "mm": 1e3, "millimeter": 1e3}
STACK_AXES = {"Z", "I", "Q"}  # tifffile's names for the axis of a page stack (Z, or image/unknown sequence)
MEMORY_SHARE = 0.5  # an image may take at most this share of the available memory, as float32


@dataclass(frozen=True)
class Stack:
    """An image as read: values [z,] y, x and voxel sizes [dz,] dy, dx in µm from the file (None: not stated)."""

    values: np.ndarray
    voxel: tuple[float, ...] | None


def _unit(text: str, where: str) -> float:
    factor = MICRONS.get(str(text).strip().lower())
    if factor is None:
        raise InvalidAt("voxel", f"{where} states sizes in {text!r}, not a length biostudy knows (um, nm, mm); "
                                 "give voxel = [dz, dy, dx] in µm")
    return factor


def _imagej_voxel(tif, ndim: int) -> tuple[float, ...] | None:
    meta = tif.imagej_metadata or {}
    page = tif.pages[0]
    try:
        sizes = [page.tags[name].value for name in ("YResolution", "XResolution")]
    except KeyError:
        return None
    pixels_per_unit = [num / den for num, den in sizes]
    if "unit" not in meta or any(p <= 0 for p in pixels_per_unit) or (ndim == 3 and "spacing" not in meta):
        return None
    factor = _unit(meta["unit"], "its ImageJ metadata")
    yx = tuple(factor / p for p in pixels_per_unit)
    return ((float(meta["spacing"]) * factor, *yx) if ndim == 3 else yx)


def _ome_voxel(tif, ndim: int) -> tuple[float, ...] | None:
    try:
        root = ET.fromstring(tif.ome_metadata)
    except ET.ParseError:
        return None
    pixels = next((e for e in root.iter() if e.tag.endswith("Pixels")), None)
    if pixels is None:
        return None
    sizes = []
    for axis in ("Z", "Y", "X")[3 - ndim:]:
        value = pixels.get(f"PhysicalSize{axis}")
        if value is None:
            return None
        sizes.append(float(value) * _unit(pixels.get(f"PhysicalSize{axis}Unit", "µm"), "its OME metadata"))
    return tuple(sizes)


def _available() -> int:
    import psutil

    return psutil.virtual_memory().available


def _fits(shape: tuple[int, ...], path: str) -> None:
    need = math.prod(shape) * 4
    if need > MEMORY_SHARE * _available():
        raise InvalidAt("path", f"{path}: {value_text(list(shape))} voxels would need {need / 1e9:.3g} GB of "
                                f"memory, {_available() / 1e9:.3g} GB available; crop or bin the stack first")


def _read_tiff(path: str) -> Stack:
    import tifffile

    with tifffile.TiffFile(path) as tif:
        series = tif.series[0]
        axes = "".join(a for a, n in zip(series.axes, series.shape) if n > 1)
        extra = [a for a in axes if a not in ("Y", "X", *STACK_AXES)]
        if extra or axes.count("Y") != 1 or axes.count("X") != 1 or len(axes) > 3:
            raise InvalidAt("path", f"{path} has axes {series.axes} (shape {value_text(list(series.shape))}): "
                                    "a region takes one greyscale or segmented z-y-x stack or y-x picture (one "
                                    "channel, one time; save it so from Fiji)")
        _fits(series.shape, path)
        values = np.squeeze(series.asarray())
        voxel = None
        if tif.is_imagej:
            voxel = _imagej_voxel(tif, values.ndim)
        elif tif.is_ome:
            voxel = _ome_voxel(tif, values.ndim)
    return Stack(values, voxel)


def _read_picture(path: str) -> Stack:
    from PIL import Image as Pictures

    with Pictures.open(path) as picture:
        if picture.mode not in ("1", "L", "I", "I;16", "I;16B", "F"):
            raise InvalidAt("path", f"{path} is a colour picture (mode {picture.mode}); a region takes a greyscale "
                                    "or segmented one")
        _fits((picture.height, picture.width), path)
        return Stack(np.asarray(picture), None)


@functools.lru_cache(maxsize=4)
def read(path: str, mtime_ns: int, size: int) -> Stack:
    """An image file (TIFF stack or picture, PNG picture) with the voxel size its metadata states; read once
    however many cases of a study use it (the file's time and size are the key).  `InvalidAt` (key path) for a
    file that is not such an image."""
    try:
        image = _read_tiff(path) if Path(path).suffix.lower() in TIFF else _read_picture(path)
    except InvalidAt:
        raise
    except Exception as error:  # whatever a damaged or foreign file makes the readers raise
        raise InvalidAt("path", f"cannot read {path} as an image ({first_line(error)})") from None
    values = np.asarray(image.values)
    if values.ndim not in (2, 3) or values.dtype.kind not in "biuf":
        raise InvalidAt("path", f"{path} holds {values.dtype} values of shape {value_text(list(values.shape))}; a "
                                "region takes a z-y-x stack or a y-x picture of numbers")
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        raise InvalidAt("path", f"{path} holds NaN or infinite values")
    values.flags.writeable = False
    return Stack(values, image.voxel)


def overlap(edges: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(cells, voxels) weights along one axis: the length of each voxel inside each cell over the cell's
    length (rows sum to the share of the cell the image covers)."""
    inside = np.minimum.outer(cells[1:], edges[1:]) - np.maximum.outer(cells[:-1], edges[:-1])
    return np.clip(inside, 0.0, None) / np.diff(cells)[:, None]


def cell_average(values: np.ndarray, voxel: tuple[float, ...], origin: tuple[float, ...], spacing: float,
                 cells_shape: tuple[int, ...]) -> np.ndarray:
    """The image's average over every cell of a grid (cells_shape: (nz, ny, nx) / (ny, nx), cells of `spacing`
    from 0), voxels [z,] y, x of `voxel` sizes from `origin` ([z,] y, x), outside the image 0."""
    result = np.asarray(values, dtype=np.float64 if values.size < 1 << 24 else np.float32)
    for axis in reversed(range(values.ndim)):  # x first: the largest reduction for a fine stack
        n = values.shape[axis]
        weights = overlap(origin[axis] + voxel[axis] * np.arange(n + 1), spacing * np.arange(cells_shape[axis] + 1))
        result = np.moveaxis(np.tensordot(weights, result, axes=([1], [axis])), 0, axis)
    return np.asarray(result, dtype=float)


class Image(Shape):
    """Cells from a microscopy image (`images`): a TIFF z-y-x stack or a PNG/TIFF y-x picture, segmented, or
    greyscale with a `threshold`, or (a biofilm) phi itself with `scale`; averaged onto the grid."""

    shape: Literal["image"] = Field(description="cells from a TIFF stack or a PNG/TIFF picture")
    path: str = Field(description="image file (.tif, .tiff, .png): a z-y-x stack (3-D) or a y-x picture (2-D), "
                                  "index [k, j, i] the voxel at z_k, y_j, x_i (slice 0 at the bottom, row 0 at y = "
                                  "0); a relative path is relative to the scene file and stays inside its folder")
    voxel: list[Annotated[float, Field(gt=0)]] | None = um(
        "voxel size [dz, dy, dx] (a picture: [dy, dx]), µm; absent: from the file's ImageJ or OME metadata",
        default=None, min_length=2, max_length=3)
    origin: Point | None = um("where the image's first voxel's outer corner lies, x, y[, z], µm (default: the "
                              "grid's origin); the image may reach beyond the grid", default=None)
    threshold: float | None = Field(None, description="greyscale: voxels with values >= threshold are the region "
                                                      "(absent: the image must be segmented, 0 and one other value)")
    scale: float | None = Field(None, gt=0, description="biofilm only: phi = scale × the grey value, averaged over "
                                                        "each cell (instead of one value inside the region)")
    _image: Stack = PrivateAttr()

    @field_validator("path")
    @classmethod
    def _resolve(cls, value: str, info: ValidationInfo) -> str:
        resolved = input_path(value, info, "image file", "an image file (TIFF, PNG)")
        if Path(resolved).suffix.lower() not in PICTURES:
            raise ValueError(f"image file {value!r} is not a TIFF or PNG file (.tif, .tiff, .png)")
        return resolved

    @model_validator(mode="after")
    def _load(self):
        stat = Path(self.path).stat()
        self._image = image = read(self.path, stat.st_mtime_ns, stat.st_size)
        values = image.values
        if self.threshold is not None and self.scale is not None:
            raise InvalidAt("scale", "give threshold (segment the image) or scale (phi from the grey values), not "
                                     "both")
        if self.scale is not None and "value" in self.model_fields_set:
            raise InvalidAt("value", "with scale, phi is scale × the grey value; leave out value")
        if self.scale is not None and getattr(self, "edge", 0.0):
            raise InvalidAt("edge", "with scale, the image gives phi itself; leave out edge")
        if self.threshold is None and self.scale is None:
            top = values.max(initial=0)
            grey = np.count_nonzero((values != 0) & (values != top))
            if grey:
                raise InvalidAt("threshold", f"{self.path} is greyscale ({grey} voxels neither 0 nor {top}): give "
                                             "threshold (the region: values >= it) or, for a biofilm, scale (phi = "
                                             "scale × value)")
        if self.scale is not None and self.scale * float(values.max(initial=0)) > 1 + 1e-12:
            raise InvalidAt("scale", f"phi = {self.scale:g} × the brightest voxel {float(values.max()):g} = "
                                     f"{self.scale * float(values.max()):g} > 1; phi lies in [0, 1]")
        if self.scale is not None and values.min(initial=0) < 0:
            raise InvalidAt("scale", f"{self.path} has negative values; phi = scale × value would be negative")
        voxel = self.voxel or image.voxel
        if voxel is None:
            raise InvalidAt("voxel", f"{self.path} states no voxel size (no ImageJ or OME metadata); give voxel = "
                                     f"{'[dz, dy, dx]' if values.ndim == 3 else '[dy, dx]'} in µm")
        if len(voxel) != values.ndim:
            raise InvalidAt("voxel", f"has {len(voxel)} entries; {self.path} is {values.ndim}-D (give "
                                     f"{'[dz, dy, dx]' if values.ndim == 3 else '[dy, dx]'})")
        return self

    @property
    def voxel_size(self) -> tuple[float, ...]:
        """[dz,] dy, dx in µm: given, or from the file."""
        return tuple(self.voxel or self._image.voxel)

    def check(self, grid):
        ndim = self._image.values.ndim
        if ndim != grid.ndim:
            kind = "z-y-x stack" if ndim == 3 else "y-x picture"
            raise InvalidAt("path", f"{self.path} is a {ndim}-D {kind} (shape "
                                    f"{value_text(list(self._image.values.shape))}); the grid is {grid.ndim}-D: give "
                                    f"a {'z-y-x stack' if grid.ndim == 3 else 'y-x picture (one slice)'}")
        if self.origin is not None and len(self.origin) != grid.ndim:
            raise InvalidAt("origin", f"has {len(self.origin)} coordinates; the grid is {grid.ndim}-D")
        if not self.cells(grid).any():
            raise InvalidAt("", f"covers no cell: no cell of the grid is at least half covered by the image's "
                                f"region (the image spans {self._extent_text()})")

    def _extent_text(self) -> str:
        origin = list(reversed(self.origin)) if self.origin else [0.0] * self._image.values.ndim
        spans = [f"{axis} {o:g}..{o + n * d:g} µm" for axis, o, n, d in
                 zip("zyx"[3 - self._image.values.ndim:], origin, self._image.values.shape, self.voxel_size)]
        return ", ".join(reversed(spans))

    def _average(self, grid: Grid, of: str) -> np.ndarray:
        stat = Path(self.path).stat()
        origin = tuple(reversed(self.origin)) if self.origin else (0.0,) * grid.ndim
        return _averaged(self.path, stat.st_mtime_ns, stat.st_size, of, self.threshold, self.voxel_size, origin,
                         grid.spacing, grid.cells_shape)

    def cells(self, grid):
        if self.scale is not None:
            return self._average(grid, "values") > 0
        return self._average(grid, "region") >= 0.5

    def density(self, grid: Grid) -> np.ndarray:
        """phi per cell from the grey values (`scale`): scale × their average over the cell."""
        return self.scale * self._average(grid, "values")


@functools.lru_cache(maxsize=8)
def _averaged(path: str, mtime_ns: int, size: int, of: str, threshold: float | None, voxel: tuple[float, ...],
              origin: tuple[float, ...], spacing: float, cells_shape: tuple[int, ...]) -> np.ndarray:
    """An image's cell averages on one grid (read-only), computed once however many study cases use them: of
    its grey values ("values") or of its region ("region": 1 where value >= threshold, or where nonzero)."""
    values = read(path, mtime_ns, size).values
    if of == "region":
        values = values >= threshold if threshold is not None else values != 0
    average = cell_average(values, voxel, origin, spacing, cells_shape)
    average.flags.writeable = False
    return average
