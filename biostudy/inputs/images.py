"""Microscopy images as scene regions: a TIFF stack or a PNG/TIFF picture, read, sized and averaged onto the grid.

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

import numpy as np

from ..errors import InvalidAt, first_line
from ..formatting import value_text

TIFF = (".tif", ".tiff")
PICTURES = (".png", *TIFF)
MICRONS = {"um": 1.0, "\u00b5m": 1.0, "\u03bcm": 1.0, "micron": 1.0, "microns": 1.0, "micrometer": 1.0,
           "nm": 1e-3, "nanometer": 1e-3, "mm": 1e3, "millimeter": 1e3}
STACK_AXES = {"Z", "I", "Q"}  # tifffile's names for the axis of a page stack (Z, or image/unknown sequence)
MEMORY_SHARE = 0.5  # an image may take at most this share of the available memory, as float32


@dataclass(frozen=True)
class Image:
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


def _read_tiff(path: str) -> Image:
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
    return Image(values, voxel)


def _read_picture(path: str) -> Image:
    from PIL import Image as Pictures

    with Pictures.open(path) as picture:
        if picture.mode not in ("1", "L", "I", "I;16", "I;16B", "F"):
            raise InvalidAt("path", f"{path} is a colour picture (mode {picture.mode}); a region takes a greyscale "
                                    "or segmented one")
        _fits((picture.height, picture.width), path)
        return Image(np.asarray(picture), None)


@functools.lru_cache(maxsize=4)
def read(path: str, mtime_ns: int, size: int) -> Image:
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
    return Image(values, image.voxel)


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
