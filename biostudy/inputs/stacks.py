"""Confocal stacks a lab measures (``biostudy measure``): one stack, several (a time series, one file per time),
or a hyperstack whose frames are the times.

A stack is read as an image region's is (`image_files`): a regular file of at
most `STACK_BYTES`, checked before it is opened; its axes as the file says
them (plus, here, a time axis T first: one frame per time); refused in one
line when truncated, of another kind (colour, channels) or larger than the
memory measuring it needs, judged from its header before a pixel is read
(`MEASURING`).  Voxel sizes come from the ImageJ or OME metadata, or are given
(``--voxel dz,dy,dx``, which wins), and are checked as a scene's `voxel`.  A
greyscale stack needs a threshold (biofilm: values >= it); a segmented one
(0 and one other value) does not.  Every problem is a `BadInput` naming the
file (or the option).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadInput, InvalidAt
from ..formatting import value_text
from .files import checked
from .image_files import TIFF, VOXEL_MAX, Use, grey_voxels, read

STACKS = (".png", *TIFF)
STACK_BYTES = 1 << 38  # 256 GiB: what a file may be before it is opened; the memory check decides below that
# Peak bytes per voxel of one frame beyond the values while it is measured: the biofilm's booleans (1), the
# connected-volume filter's labels (int32: 4) and what it keeps (1), a face count's int8 differences (1).  Measured
# on a 64 x 512 x 512 uint8 stack, values included: 7.06 with `connected` (VmHWM 7.08), 3.17 without
# (tracemalloc; `python benchmarks/image_memory.py --measure`).
MEASURING = Use("measuring", 8, frames=True, taker="measure")


@dataclass(frozen=True)
class Frames:
    """A measured file's values [t, [z,] y, x] (one frame per time; read-only), voxel sizes [dz,] dy, dx (µm) and
    the sha256 of its bytes."""

    path: Path
    values: np.ndarray
    voxel: tuple[float, ...]
    sha256: str

    @property
    def shape(self) -> tuple[int, ...]:
        """[nz,] ny, nx of one frame."""
        return tuple(self.values.shape[1:])


def _voxel(given: list[float] | None, path: Path, ndim: int, stated, problem: str) -> tuple[float, ...]:
    wanted = "dz,dy,dx" if ndim == 3 else "dy,dx"
    if given is not None:
        if len(given) != ndim:
            raise BadInput(f"has {len(given)} entries; {path} is {ndim}-D (give {wanted} in µm)", None, "voxel")
        bad = [v for v in given if not (math.isfinite(v) and 0 < v <= VOXEL_MAX)]
        if bad:
            raise BadInput(f"{value_text(bad[0])} is not a voxel size (a length in (0, {VOXEL_MAX:g}] µm)", None,
                           "voxel")
        return tuple(float(v) for v in given)
    if stated is None:
        why = problem or f"{path} states no voxel size (no ImageJ or OME metadata)"
        raise BadInput(f"{why}; give the voxel size (voxel: {wanted} in µm)")
    return tuple(stated)


def load(path: str | Path, voxel: list[float] | None = None) -> Frames:
    """A stack file for measuring: its frames and voxel sizes (module docstring); `BadInput` in one line."""
    path = Path(path)
    found = checked(path, STACK_BYTES, "a TIFF stack or PNG picture")
    if path.suffix.lower() not in STACKS:
        raise BadInput("is not a TIFF or PNG file (.tif, .tiff, .png)", path)
    try:
        stack = read(str(path), found.st_mtime_ns, found.st_size, MEASURING)
    except InvalidAt as error:  # its problem names the file
        raise BadInput(error.problem) from None
    values = stack.values
    return Frames(path, values, _voxel(voxel, path, values.ndim - 1, stack.voxel, stack.voxel_problem), stack.sha256)


def region(values: np.ndarray, threshold: float | None, path: Path) -> np.ndarray:
    """The biofilm voxels of one frame: values >= `threshold`, or the nonzero ones of a segmented stack; a
    greyscale stack without a threshold is `BadInput`."""
    if threshold is not None:
        return values >= threshold
    grey, top = grey_voxels(values)
    if grey:
        raise BadInput(f"{path} is greyscale ({grey} voxels neither 0 nor {top}): give a threshold (biofilm: values "
                       ">= it)", None, "threshold")
    return values != 0
