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
from the scene (`voxel`, which wins).  Reading a file, its axes and what is
refused before anything large is allocated: `image_files`.

Onto the grid: every cell takes the average of the image over the cell's
volume, each voxel weighted by how much of the cell it covers (separable
overlap weights per axis; outside the image counts as 0).  This conserves
the foreground's volume and does not depend on the cell size dividing the
voxel size; an interpolating resampler (scikit-image's `resize` with its
Gaussian anti-aliasing) would blur the foreground over cells it does not
cover.  A segmented image then covers the cells whose foreground fraction is
at least 1/2; a greyscale one does after a `threshold`, or gives phi itself
(`scale` times the cell average of the grey values).

An image larger than the grid is cropped to it (`Spill`): the share of the
image, and of its region, that lies outside is measured exactly (each
voxel by the part of it beyond the grid).  The scene refuses a biofilm image
whose biofilm would be cut, and a run says how much of any other image was
left out (`Scene.image_attrs`).  The region: voxels >= threshold, the
nonzero voxels of a segmented image, or (with `scale`) the voxels whose
phi = scale × value is biofilm (>= 0.5, as a run's biofilm_volume counts).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Callable, Literal

import numpy as np
from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from solver import Grid
from solver.series import BIOFILM_THRESHOLD

from ..errors import InvalidAt
from ..formatting import value_text
from .geometry import Point, Shape, input_path, um
from .image_files import SLAB_VOXELS, TIFF, VOXEL_MAX, Stack, averaging_bytes, grey_voxels, read

PICTURES = (".png", *TIFF)
SPILL_TOLERANCE = 1e-9  # of an image's volume: a voxel edge rounded past the grid's by floating point is inside


@dataclass(frozen=True)
class Spill:
    """How much of an image lies outside the grid: `image` its volume's share, `region` its region's share (by
    voxel volume) and `voxels` the region's voxels reaching outside; `spans` and `grid` the extents, said."""

    image: float
    region: float
    voxels: int
    spans: str
    grid: str


def inside_share(edges: np.ndarray, top: float) -> np.ndarray:
    """Per voxel along one axis (voxel edges `edges`), the share of its length inside [0, top]."""
    inside = np.clip(np.minimum(edges[1:], top) - np.maximum(edges[:-1], 0.0), 0.0, None)
    return inside / np.diff(edges)


def weighted_count(mask: np.ndarray, weights: list[np.ndarray]) -> float:
    """sum of mask[k, j, i] w_z[k] w_y[j] w_x[i] (2-D: without z), one plane at a time (no float copy of a
    stack)."""
    if mask.ndim == 2:
        return float(weights[0] @ mask.astype(float) @ weights[1])
    return float(sum(w * weighted_count(plane, weights[1:]) for w, plane in zip(weights[0], mask) if w))


def overlap(edges: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(cells, voxels) weights along one axis: the length of each voxel inside each cell over the cell's
    length (rows sum to the share of the cell the image covers)."""
    inside = np.minimum.outer(cells[1:], edges[1:]) - np.maximum.outer(cells[:-1], edges[:-1])
    return np.clip(inside, 0.0, None) / np.diff(cells)[:, None]


def cell_average(values: np.ndarray, voxel: tuple[float, ...], origin: tuple[float, ...], spacing: float,
                 cells_shape: tuple[int, ...], of: Callable[[np.ndarray], np.ndarray] = np.asarray) -> np.ndarray:
    """The image's average over every cell of a grid (cells_shape: (nz, ny, nx) / (ny, nx), cells of `spacing`
    from 0), voxels [z,] y, x of `voxel` sizes from `origin` ([z,] y, x), outside the image 0; of `of(values)`
    (a region: values >= threshold), taken a slab of `SLAB_VOXELS` at a time along the first axis: the other
    axes are reduced slab by slab (x first: the largest reduction for a fine stack), then the first, so that
    the float copies of the whole stack are never made (1.9 GB for a 128 MB stack)."""
    dtype = np.float64 if values.size < 1 << 24 else np.float32
    weights = [overlap(origin[axis] + voxel[axis] * np.arange(n + 1), spacing * np.arange(cells_shape[axis] + 1))
               for axis, n in enumerate(values.shape)]
    rows = max(1, SLAB_VOXELS // max(1, math.prod(values.shape[1:])))
    reduced = []
    for start in range(0, values.shape[0], rows):
        block = np.asarray(of(values[start:start + rows]), dtype=dtype)
        for axis in reversed(range(1, values.ndim)):
            block = np.moveaxis(np.tensordot(weights[axis], block, axes=([1], [axis])), 0, axis)
        reduced.append(block)
    result = np.tensordot(weights[0], np.concatenate(reduced, axis=0), axes=([1], [0]))
    return np.asarray(result, dtype=float)


class Image(Shape):
    """Cells from a microscopy image (`images`): a TIFF z-y-x stack or a PNG/TIFF y-x picture, segmented, or
    greyscale with a `threshold`, or (a biofilm) phi itself with `scale`; averaged onto the grid."""

    shape: Literal["image"] = Field(description="cells from a TIFF stack or a PNG/TIFF picture")
    path: str = Field(description="image file (.tif, .tiff, .png): a z-y-x stack (3-D) or a y-x picture (2-D), "
                                  "index [k, j, i] the voxel at z_k, y_j, x_i (slice 0 at the bottom, row 0 at y = "
                                  "0); a relative path is relative to the scene file and stays inside its folder")
    voxel: list[Annotated[float, Field(gt=0, le=VOXEL_MAX)]] | None = um(
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
            grey, top = grey_voxels(values)
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
        wanted = "[dz, dy, dx]" if values.ndim == 3 else "[dy, dx]"
        if voxel is None and image.voxel_problem:
            raise InvalidAt("voxel", f"{image.voxel_problem}; give voxel = {wanted} in µm")
        if voxel is None:
            raise InvalidAt("voxel", f"{self.path} states no voxel size (no ImageJ or OME metadata); give voxel = "
                                     f"{wanted} in µm")
        if len(voxel) != values.ndim:
            raise InvalidAt("voxel", f"has {len(voxel)} entries; {self.path} is {values.ndim}-D (give "
                                     f"{wanted})")
        return self

    def memory(self) -> tuple[str, float, float]:
        """(the file, bytes its values hold once read: for the run, cached per file; bytes averaging them onto
        a grid holds besides, at most) for `resources.estimate`."""
        values = self._image.values
        return (self.path, *averaging_bytes(values.shape, values.dtype.itemsize))

    @property
    def voxel_size(self) -> tuple[float, ...]:
        """[dz,] dy, dx in µm: given, or from the file."""
        return tuple(self.voxel or self._image.voxel)

    def check(self, grid):
        ndim = self._image.values.ndim
        if ndim != grid.ndim:
            kind = "z-y-x stack" if ndim == 3 else "y-x picture"
            if self._image.values.shape[0] == 1 and ndim == 3:
                kind = "z-y-x stack of one slice (the file states its z spacing or axis)"
            raise InvalidAt("path", f"{self.path} is a {ndim}-D {kind} (shape "
                                    f"{value_text(list(self._image.values.shape))}); the grid is {grid.ndim}-D: give "
                                    f"a {'z-y-x stack' if grid.ndim == 3 else 'y-x picture (one slice)'}")
        if self.origin is not None and len(self.origin) != grid.ndim:
            raise InvalidAt("origin", f"has {len(self.origin)} coordinates; the grid is {grid.ndim}-D")
        if not self.cells(grid).any():
            raise InvalidAt("", f"covers no cell: no cell of the grid is at least half covered by the image's "
                                f"region (the image spans {self._extent_text()})")

    def _extent_text(self) -> str:
        spans = [f"{axis} {o:g}..{o + n * d:g} µm" for axis, o, n, d in
                 zip("zyx"[3 - self._image.values.ndim:], self._origin(), self._image.values.shape, self.voxel_size)]
        return ", ".join(reversed(spans))

    def _origin(self) -> tuple[float, ...]:
        """The image's first corner, [z,] y, x (µm)."""
        return tuple(reversed(self.origin)) if self.origin else (0.0,) * self._image.values.ndim

    @property
    def sha256(self) -> str:
        return self._image.sha256

    @property
    def image_shape(self) -> tuple[int, ...]:
        """[nz,] ny, nx voxels."""
        return tuple(self._image.values.shape)

    def spill(self, grid: Grid) -> Spill | None:
        """How much of the image (and of its region) the grid leaves out (`Spill`); None when it lies inside."""
        stat = Path(self.path).stat()
        found = _spill(self.path, stat.st_mtime_ns, stat.st_size, self.threshold, self.scale, self.voxel_size,
                       self._origin(), tuple(reversed(grid.extent)))
        if found is None:
            return None
        image, region, voxels = found
        tops = ", ".join(f"{a} 0..{top:g} µm" for a, top in zip(grid.axes, grid.extent))
        return Spill(image, region, voxels, self._extent_text(), tops)

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
    region = (lambda block: block >= threshold) if threshold is not None else (lambda block: block != 0)
    average = cell_average(values, voxel, origin, spacing, cells_shape, region if of == "region" else np.asarray)
    average.flags.writeable = False
    return average


@functools.lru_cache(maxsize=8)
def _spill(path: str, mtime_ns: int, size: int, threshold: float | None, scale: float | None,
           voxel: tuple[float, ...], origin: tuple[float, ...], tops: tuple[float, ...]):
    """(image share, region share, region voxels) outside [0, tops] ([z,] y, x), or None if the image lies inside
    (to `SPILL_TOLERANCE`); computed once per image and grid, a slab of `SLAB_VOXELS` at a time (no copy of a
    stack's size: what its region's memory counts, `image_files.averaging_bytes`)."""
    values = read(path, mtime_ns, size).values
    shares = [inside_share(o + d * np.arange(n + 1), top) for o, d, n, top in zip(origin, voxel, values.shape, tops)]
    image = 1.0 - float(np.prod([s.mean() for s in shares]))
    if image <= SPILL_TOLERANCE:
        return None
    rows = max(1, SLAB_VOXELS // max(1, math.prod(values.shape[1:])))  # a slab at a time, as the averaging
    count, inside, voxels = 0, 0.0, 0
    for start in range(0, values.shape[0], rows):
        block = values[start:start + rows]
        if scale is not None:
            region = scale * block >= BIOFILM_THRESHOLD
        else:
            region = block >= threshold if threshold is not None else block != 0
        slab = [shares[0][start:start + rows], *shares[1:]]
        count += int(np.count_nonzero(region))
        inside += weighted_count(region, slab)
        reaching = np.zeros(region.shape, bool)  # voxels not wholly inside
        for axis, share in enumerate(slab):
            reaching |= (share < 1.0 - SPILL_TOLERANCE).reshape([-1 if a == axis else 1 for a in range(region.ndim)])
        voxels += int(np.count_nonzero(region & reaching))
    outside = count - inside if count else 0.0
    if outside <= SPILL_TOLERANCE * max(count, 1):
        return image, 0.0, 0
    return image, outside / count, voxels
