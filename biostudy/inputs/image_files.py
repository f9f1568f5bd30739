"""Reading a microscopy image file for an image region (`images.Image`): a TIFF stack or picture, a PNG picture,
its axes and the voxel size its metadata states, refused in one line before anything large is allocated.

Axes are what the file says, not what its sizes suggest: a TIFF's y and x
stay axes when they are one pixel long (a 1 × 1 picture is a picture), and a
single slice is a z-stack of one slice when the file says so (a z spacing in
ImageJ or OME metadata, a z axis in the shape tifffile recorded), else a y-x
picture.  A file that ends before its pages do (an ImageJ stack short of the
images its metadata declares, a chain of pages or pixels past the end) is
refused, not read as its first pages.  A palette picture (PNG or TIFF) is
greyscale when its palette is grey, read through it; a colour one is refused.

Voxel sizes from metadata are checked as the scene's `voxel` is (a finite
length in (0, `VOXEL_MAX`] µm); a bad one is told, naming the file and the
metadata field, only when the scene does not give `voxel` (which wins).

Memory: a file is refused when reading and averaging it would not fit in the
memory a run may use (`resources.memory_limits`: the machine's, a batch
job's cgroup limit, or BIOSTUDY_MEMORY), judged by the size its header
declares before any pixel is read.
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import math
import struct
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadInput, InvalidAt, first_line
from ..formatting import value_text
from .resources import too_big

TIFF = (".tif", ".tiff")
MICRONS = {"um": 1.0, "\u00b5m": 1.0, "\u03bcm": 1.0, "micron": 1.0, "microns": 1.0, "micrometer": 1.0,
           "nm": 1e-3, "nanometer": 1e-3, "mm": 1e3, "millimeter": 1e3}
STACK_AXES = {"Z", "I", "Q"}  # tifffile's names for the axis of a page stack (Z, or image/unknown sequence)
# Pillow's greyscale modes and the bytes a pixel takes in them (a grey palette, "P", is converted to "L")
GREY_BYTES = {"1": 1, "L": 1, "P": 1, "I": 4, "I;16": 2, "I;16B": 2, "F": 4}
VOXEL_MAX = 1e6  # µm: a voxel up to a metre; 1e300 would make the image's extent overflow
# Peak bytes per voxel of averaging a slab of a stack beyond its values (their item size, read once and held by
# the cache): the region's booleans (1) and the averaging's float copies (up to 13: above 2^24 voxels the float32
# copy is cast to float64 inside tensordot).  Measured on 64 x 512 x 512 stacks averaged whole, region by
# threshold, in all: uint8 15.07 bytes a voxel (tracemalloc; VmHWM 15.38), uint16 16.07 (16.38), float32 18.07
# (18.38); below 2^24 voxels less (uint8 32 x 512 x 512: 11.15).  A stack is averaged `SLAB_VOXELS` at a time
# (`images.cell_average`): these bytes are paid for a slab, not for the stack.
# `python benchmarks/image_memory.py [--dtype uint16]`.
AVERAGING_BYTES = 14
SLAB_VOXELS = 1 << 22  # voxels averaged at once (whole slices along the first axis, one at least)


def averaging_bytes(shape: tuple[int, ...], itemsize: int) -> tuple[float, float]:
    """(bytes an image of `shape` holds once read, bytes its averaging onto a grid holds besides, at most)."""
    voxels = math.prod(shape)
    rows = max(1, SLAB_VOXELS // max(1, math.prod(shape[1:])))
    return float(voxels * itemsize), float(min(voxels, rows * math.prod(shape[1:])) * AVERAGING_BYTES)


@dataclass(frozen=True)
class Stack:
    """An image as read: values [z,] y, x and voxel sizes [dz,] dy, dx in µm from the file (None: not stated,
    or why the stated ones are unusable in `voxel_problem`)."""

    values: np.ndarray
    voxel: tuple[float, ...] | None
    voxel_problem: str = ""
    sha256: str = ""  # of the file's bytes, for the provenance of what is made from it


class BadMetadata(ValueError):
    """The voxel size a file's metadata states is unusable (the message says which field, and why)."""


def _length(value, factor: float, stated: str) -> float:
    """A voxel length from metadata in µm (`stated`: the field and value as the file gives them), checked as
    the scene's `voxel`: finite, in (0, VOXEL_MAX]."""
    try:
        size = float(value) * factor
    except (TypeError, ValueError):
        raise BadMetadata(f"{stated} is not a number") from None
    if not math.isfinite(size) or not 0 < size <= VOXEL_MAX:
        raise BadMetadata(f"{stated} is not a voxel size (a length in (0, {VOXEL_MAX:g}] µm)")
    return size


def _unit(text: str, field: str) -> float:
    factor = MICRONS.get(str(text).strip().lower())
    if factor is None:
        raise BadMetadata(f"{field} = {text!r} is not a length biostudy knows (um, nm, mm)")
    return factor


def _imagej_voxel(tif, ndim: int) -> tuple[float, ...] | None:
    meta = tif.imagej_metadata or {}
    try:
        sizes = {name: tif.pages[0].tags[name].value for name in ("YResolution", "XResolution")}
    except KeyError:
        return None
    if "unit" not in meta:
        return None
    if ndim == 3 and "spacing" not in meta:
        raise BadMetadata(f"ImageJ spacing is missing (Fiji leaves it out when it is 1 {meta['unit']})")
    factor = _unit(meta["unit"], "ImageJ unit")
    yx = [_length(den / num if num > 0 and den > 0 else 0.0, factor, f"{name} = {num}/{den} pixels per {meta['unit']}")
          for name, (num, den) in sizes.items()]
    spacing = meta.get("spacing")
    return (_length(spacing, factor, f"ImageJ spacing = {spacing} {meta['unit']}"), *yx) if ndim == 3 else tuple(yx)


def _ome_pixels(tif):
    try:
        root = ET.fromstring(tif.ome_metadata)
    except ET.ParseError:
        return None
    return next((e for e in root.iter() if e.tag.endswith("Pixels")), None)


def _ome_voxel(tif, ndim: int) -> tuple[float, ...] | None:
    pixels = _ome_pixels(tif)
    if pixels is None:
        return None
    sizes = []
    for axis in ("Z", "Y", "X")[3 - ndim:]:
        value = pixels.get(f"PhysicalSize{axis}")
        if value is None:
            return None
        unit = _unit(pixels.get(f"PhysicalSize{axis}Unit", "µm"), f"OME PhysicalSize{axis}Unit")
        sizes.append(_length(value, unit, f"OME PhysicalSize{axis} = {value}"))
    return tuple(sizes)


def _states_z(tif, series) -> bool:
    """Whether the file says its single slice is one of a z-stack: its metadata gives a z spacing (ImageJ, OME;
    Fiji writes none for a single image), or the axes tifffile recorded name z (an unnamed one, Q, does not)."""
    if tif.is_imagej:
        return "spacing" in (tif.imagej_metadata or {})
    if tif.is_ome:
        pixels = _ome_pixels(tif)
        return pixels is not None and pixels.get("PhysicalSizeZ") is not None
    return tif.is_shaped and "Z" in series.get_axes(False)


@dataclass(frozen=True)
class Use:
    """What is done with an image once read, for the memory it is judged against: a region's averaging onto the
    grid (`AVERAGING`), or ``biostudy measure`` (`inputs.stacks.MEASURING`: frames along a time axis allowed)."""

    doing: str  # "averaging": the memory problem says "reading and averaging it needs ..."
    per_voxel: int  # bytes a voxel of one frame takes beyond the values, while it is worked on
    frames: bool = False  # a leading time axis (T) is allowed: values [t, [z,] y, x]
    taker: str = "a region"  # what takes the image, in messages: "a region takes a greyscale or segmented one"
    slabs: bool = False  # worked on `SLAB_VOXELS` at a time: `per_voxel` paid for a slab, not for the stack


AVERAGING = Use("averaging", AVERAGING_BYTES, slabs=True)


def _fits(shape: tuple[int, ...], itemsize: int, path: str, use: Use = AVERAGING) -> None:
    frame = shape[1:] if use.frames else shape
    try:
        need = (sum(averaging_bytes(shape, itemsize)) if use.slabs
                else math.prod(shape) * itemsize + math.prod(frame) * use.per_voxel)
        problem = too_big(need, f"reading and {use.doing} it needs")
    except BadInput as error:  # BIOSTUDY_MEMORY is not a size
        raise InvalidAt("path", str(error)) from None
    if problem:
        raise InvalidAt("path", f"{path}: {value_text(list(shape))} voxels: {problem}; crop or bin the stack first")


def _truncated(tif, series, path: str) -> None:
    """Refuse a file that ends before its pages do (tifffile reads what it finds and logs the rest away): an
    ImageJ file holding fewer images than its metadata declares, a chain of pages pointing past the end, or a
    page's pixels lying beyond it."""
    if tif.is_imagej:
        declared = int((tif.imagej_metadata or {}).get("images", 1))
        held = math.prod(n for a, n in zip(series.get_axes(False), series.get_shape(False)) if a not in "YXS")
        if declared != held:
            raise InvalidAt("path", f"{path}: its ImageJ metadata declares {declared} images, the file holds {held} "
                                    "(truncated or damaged); save the stack again")
    handle, size = tif.filehandle, tif.filehandle.size
    handle.seek(tif.pages.next_page_offset)  # where the last page read stores the offset of the next: 0 at the end
    link = handle.read(tif.tiff.offsetsize)
    ends = [o + n for page in series.pages if page is not None for o, n in zip(page.dataoffsets, page.databytecounts)]
    broken = len(link) < tif.tiff.offsetsize or struct.unpack(tif.tiff.offsetformat, link)[0]
    if broken or max(ends, default=0) > size:
        raise InvalidAt("path", f"{path} ends before its pages do ({size} bytes; truncated or damaged); save the "
                                "stack again")


def _palette(page, values: np.ndarray, path: str, use: Use) -> np.ndarray:
    """A palette TIFF's values through its palette when it is grey (r = g = b), refused when it is colour."""
    red, green, blue = page.colormap
    if not (np.array_equal(red, green) and np.array_equal(red, blue)):
        raise InvalidAt("path", f"{path} is a colour picture (a colour palette); {use.taker} takes a greyscale or "
                                "segmented one")
    return (red >> 8).astype(np.uint8)[values] if page.bitspersample == 8 else red[values]


def _shape(tif, series, path: str, use: Use) -> tuple[int, ...]:
    """The image's [z,] y, x sizes as the file's axes say (module docstring), after the number of frames when `use`
    takes a time axis (T, the first of the file's axes); `InvalidAt` for other axes."""
    kept = [(a, n) for a, n in zip(series.get_axes(False), series.get_shape(False)) if n > 1 or a in "YX"]
    frames = [n for a, n in kept if a == "T"] if use.frames and kept[0][0] == "T" else []
    kept = kept[len(frames):]
    if _states_z(tif, series) and not any(a in STACK_AXES for a, _ in kept):
        kept.insert(0, ("Z", 1))
    axes = "".join(a for a, _ in kept)
    extra = [a for a in axes if a not in ("Y", "X", *STACK_AXES)]
    if extra or axes.count("Y") != 1 or axes.count("X") != 1 or len(axes) > 3:
        times = ", a time series as frames (T first)" if use.frames else ", one time"
        raise InvalidAt("path", f"{path} has axes {series.axes} (shape {value_text(list(series.shape))}): "
                                f"{use.taker} takes one greyscale or segmented z-y-x stack or y-x picture (one "
                                f"channel{times}; save it so from Fiji)")
    space = tuple(n for _, n in kept)
    return (*(frames or [1]), *space) if use.frames else space


def _read_tiff(path: str, use: Use) -> Stack:
    import tifffile

    with tifffile.TiffFile(path) as tif:
        series = tif.series[0]
        _truncated(tif, series, path)
        shape = _shape(tif, series, path, use)
        _fits(shape, series.dtype.itemsize, path, use)
        values = series.asarray().reshape(shape)
        if series.pages[0].photometric == tifffile.PHOTOMETRIC.PALETTE:
            values = _palette(series.pages[0], values, path, use)
        voxel, problem = None, ""
        ndim = values.ndim - use.frames
        try:
            if tif.is_imagej:
                voxel = _imagej_voxel(tif, ndim)
            elif tif.is_ome:
                voxel = _ome_voxel(tif, ndim)
        except BadMetadata as error:
            problem = f"{path}: its metadata's {error}"
    return Stack(values, voxel, problem)


def _read_picture(path: str, use: Use) -> Stack:
    from PIL import Image as Pictures

    with warnings.catch_warnings():  # above 89 M pixels: biostudy's memory check decides, in one line
        warnings.simplefilter("ignore", Pictures.DecompressionBombWarning)
        opened = Pictures.open(path)
    with opened as picture:
        grey = picture.mode == "P" and _grey_palette(picture)
        if picture.mode not in GREY_BYTES or picture.mode == "P" and not grey:
            raise InvalidAt("path", f"{path} is a colour picture (mode {picture.mode}"
                                    f"{', a colour palette' if picture.mode == 'P' else ''}); {use.taker} takes a "
                                    "greyscale or segmented one")
        shape = (1,) * use.frames + (picture.height, picture.width)
        _fits(shape, 2 * GREY_BYTES[picture.mode], path, use)  # Pillow's pixels, numpy's
        return Stack(np.asarray(picture.convert("L") if grey else picture).reshape(shape), None)


def _grey_palette(picture) -> bool:
    """Whether a palette picture's palette is grey: every entry r = g = b."""
    entries = np.asarray(picture.getpalette("RGB") or [], dtype=np.uint8).reshape(-1, 3)
    return bool((entries == entries[:, :1]).all())


def grey_voxels(values: np.ndarray) -> tuple[int, float]:
    """How many voxels are neither 0 nor the largest value (0 for a segmented image), and that value."""
    top = values.max(initial=0)
    return int(np.count_nonzero((values != 0) & (values != top))), top


@contextlib.contextmanager
def _tifffile_quiet():
    """tifffile logs what it finds wrong in a file (to stderr, before biostudy's one line); biostudy says it."""
    logger = logging.getLogger("tifffile")
    silence = logging.Filter("no such logger")  # passes no record of "tifffile"
    logger.addFilter(silence)
    try:
        yield
    finally:
        logger.removeFilter(silence)


@functools.lru_cache(maxsize=4)
def read(path: str, mtime_ns: int, size: int, use: Use = AVERAGING) -> Stack:
    """An image file (TIFF stack or picture, PNG picture) with the voxel size its metadata states; read once
    however many cases of a study use it (the file's time and size are the key).  `InvalidAt` (key path) for a
    file that is not such an image.  `use`: what is done with it (`Use`; with frames, values [t, [z,] y, x])."""
    try:
        with _tifffile_quiet():
            image = _read_tiff(path, use) if Path(path).suffix.lower() in TIFF else _read_picture(path, use)
    except InvalidAt:
        raise
    except Exception as error:  # whatever a damaged or foreign file makes the readers raise
        raise InvalidAt("path", f"cannot read {path} as an image ({first_line(error)})") from None
    values = np.asarray(image.values)
    if values.ndim - use.frames not in (2, 3) or values.dtype.kind not in "biuf":
        raise InvalidAt("path", f"{path} holds {values.dtype} values of shape {value_text(list(values.shape))}; "
                                f"{use.taker} takes a z-y-x stack or a y-x picture of numbers")
    if values.dtype.kind == "f" and not np.isfinite(values).all():
        raise InvalidAt("path", f"{path} holds NaN or infinite values")
    values.flags.writeable = False
    return Stack(values, image.voxel, image.voxel_problem, file_sha256(path))


def file_sha256(path: str) -> str:
    """The sha256 of a file's bytes, read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
