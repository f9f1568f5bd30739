"""COMSTAT's own definitions on the segmented cells, and its connected-volume filtering.

`substratum` measures a run sub-cell (the interpolated level set: continuous in phi, what a fit needs).  A lab
compares with COMSTAT (Heydorn et al. 2000, Microbiology 146:2395), which measures a thresholded confocal
stack voxel by voxel; its surface, a staircase of voxel faces, is larger than a smooth surface's (a
hemisphere's ratio 3/r becomes ~4.5/r), so a fit of sub-cell values to a COMSTAT table is biased.  With
`[substratum] estimator = "voxel"` every observable is COMSTAT's count on the cells, each cell a voxel
(biofilm where phi >= threshold; an obstacle is background):

* biomass = biofilm voxels x voxel volume / substratum area,
* thickness of a column = the top of its topmost biofilm voxel (pores below ignored); mean and maximum over all
  columns, bare ones as zero; roughness Ra* = mean |L - L̄| / L̄ over the columns,
* coverage = the biofilm fraction of the first layer on the substratum,
* surface = the voxel faces between biofilm and background inside the domain (the substratum plane, the side
  walls and the top of the stack are not background, so they are not surface), over the biovolume.

`connected` is COMSTAT's connected-volume filtering: biofilm not connected to the substratum through biofilm
voxels sharing a face is background (a floating piece does not count).  It applies to either estimator: the
filtered field keeps phi where the biofilm stays and is 0 where a floating piece was.  Off by default: a
piece that detaches then leaves every observable at once, a jump a finite-difference Jacobian cannot take.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..inputs.substratum_face import normal_axis
from .substratum import THRESHOLD, on_substratum, substratum_area


def connected(phi: np.ndarray, face: str, threshold: float = THRESHOLD) -> np.ndarray:
    """phi (solver order, obstacles NaN) with the biofilm not connected to the substratum face set to 0."""
    field = on_substratum(phi, face)
    labels, _ = ndimage.label(field >= threshold)  # face neighbours (6 in 3-D, 4 in 2-D)
    floating = (labels > 0) & ~np.isin(labels, labels[0][labels[0] > 0])
    kept = np.where(floating, 0.0, field)
    if face[1] == "+":
        kept = kept[::-1]
    return np.where(np.isnan(phi), np.nan, np.moveaxis(kept, 0, normal_axis(face, phi.ndim)))


def _columns(voxels: np.ndarray, h: float) -> np.ndarray:
    """Per column normal to the substratum: the top of its topmost biofilm voxel above the substratum (µm)."""
    n = voxels.shape[0]
    topmost = n - np.argmax(voxels[::-1], axis=0)
    return np.where(voxels.any(axis=0), topmost * h, 0.0)


def _surface(voxels: np.ndarray) -> int:
    """Faces between biofilm and background voxels, inside the domain."""
    return sum(int(np.count_nonzero(np.diff(voxels.astype(np.int8), axis=axis))) for axis in range(voxels.ndim))


def voxel_observables(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> dict[str, float]:
    """COMSTAT's six observables counted on the cells (module docstring), units as `substratum.QUANTITIES`."""
    voxels = on_substratum(phi, face) >= threshold
    area = substratum_area(phi, h, face)
    volume = float(np.count_nonzero(voxels)) * h**voxels.ndim
    thickness = _columns(voxels, h)
    mean = float(thickness.mean())
    return {
        "biomass": volume / area,
        "mean_thickness": mean,
        "max_thickness": float(thickness.max()),
        "roughness": float(np.mean(np.abs(thickness - mean)) / mean) if mean > 0 else float("nan"),
        "coverage": float(voxels[0].mean()),
        "surface_to_biovolume": _surface(voxels) * h ** (voxels.ndim - 1) / volume if volume > 0 else float("nan"),
    }
