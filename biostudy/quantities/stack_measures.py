"""COMSTAT's observables of a lab's confocal stack, by the code that measures a run (``biostudy measure``).

A calibration against COMSTAT numbers is only as good as the agreement of their definitions; so a stack is
measured by `comstat.counted`, the very count a run's ``[substratum] estimator = "voxel"`` makes on its cells,
here on the stack's own voxels ([dz,] dy, dx µm, anisotropic as confocal stacks are): biomass, mean and maximum
thickness, roughness Ra*, substratum coverage and surface to biovolume (docs/comstat.md).  Biofilm is the
voxels at or above the threshold (or the nonzero ones of a segmented stack), the substratum the face given or,
as for a scene, the face the biofilm of the first frame rests on (`inputs.substratum_face.resting_face`), and
`connected` COMSTAT's connected-volume filter (`comstat.attached`).  One row per frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from ..inputs.stacks import Frames, region
from ..inputs.substratum_face import resting_face
from . import comstat
from .substratum import QUANTITIES

OBSERVABLES = tuple(QUANTITIES)  # biomass, mean_thickness, max_thickness, roughness, coverage, surface_to_biovolume


@dataclass(frozen=True)
class Measured:
    """One file's rows (one per frame: its observables in `substratum.QUANTITIES` units), and how they were
    measured: the substratum face, the threshold, the filter, the voxel sizes and the file's sha256."""

    frames: Frames
    face: str
    threshold: float | None
    connected: bool
    rows: tuple[dict[str, float], ...]


def substratum(voxels: np.ndarray, face: str | None) -> str:
    """The face given, checked against the stack's dimension, or the face the biofilm rests on."""
    faces = ("x-", "x+", "y-", "y+", "z-", "z+")[: 2 * voxels.ndim]
    if face is not None:
        if face not in faces:
            raise BadInput(f"{face!r} is not a face of a {voxels.ndim}-D stack ({', '.join(faces)})", None,
                           "substratum")
        return face
    found = resting_face(voxels, held=())
    if found.face is None:  # a tie, or a biofilm touching no face: say why as for a scene, and what to give
        why = found.why_none.split(" left out: ", 1)[-1].split("; name the substratum")[0]
        raise BadInput(f"{why}: give the substratum (its face: {', '.join(faces)})", None, "substratum")
    return found.face


def frame_observables(voxels: np.ndarray, voxel: tuple[float, ...], face: str, connected: bool) -> dict[str, float]:
    """COMSTAT's six observables of one frame's boolean biofilm voxels ([z,] y, x) of `voxel` µm."""
    kept = comstat.oriented(voxels, face)
    if connected:
        kept = comstat.attached(kept)
    return comstat.counted(kept, comstat.spacings(voxel, face, voxels.ndim))


def measure(frames: Frames, threshold: float | None = None, face: str | None = None,
            connected: bool = False) -> Measured:
    """Every frame of a file measured (module docstring); `BadInput` for a greyscale stack without threshold, a
    face that is not one or a substratum no rule decides."""
    rows = []
    for values in frames.values:
        voxels = region(values, threshold, frames.path)
        face = substratum(voxels, face)  # the first frame's, for all
        rows.append(frame_observables(voxels, frames.voxel, face, connected))
    return Measured(frames, str(face), threshold, connected, tuple(rows))
