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

`counted` is the one count, on boolean voxels of any edges: a run's cubic cells (`voxel_observables`) and a
confocal stack's anisotropic voxels ([dz,] dy, dx: `stack_measures`, ``biostudy measure``) alike.
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..inputs.substratum_face import normal_axis
from .substratum import THRESHOLD, on_substratum


def oriented(cells: np.ndarray, face: str) -> np.ndarray:
    """A (z, y, x) / (y, x) array with the substratum's normal first, index 0 next to the substratum (a view)."""
    moved = np.moveaxis(cells, normal_axis(face, cells.ndim), 0)
    return moved[::-1] if face[1] == "+" else moved


def attached(voxels: np.ndarray) -> np.ndarray:
    """Boolean biofilm voxels (oriented: the substratum's layer first) connected to that layer through voxels
    sharing a face (6 neighbours in 3-D, 4 in 2-D): COMSTAT's connected-volume filtering."""
    labels, count = ndimage.label(voxels)
    kept = np.zeros(count + 1, bool)  # per label: reaches the substratum's layer (a table, not np.isin's sort)
    kept[labels[0]] = True
    kept[0] = False
    return kept[labels]


def connected(phi: np.ndarray, face: str, threshold: float = THRESHOLD) -> np.ndarray:
    """phi (solver order, obstacles NaN) with the biofilm not connected to the substratum face set to 0."""
    field = on_substratum(phi, face)
    floating = (field >= threshold) & ~attached(field >= threshold)
    kept = np.where(floating, 0.0, field)
    if face[1] == "+":
        kept = kept[::-1]
    return np.where(np.isnan(phi), np.nan, np.moveaxis(kept, 0, normal_axis(face, phi.ndim)))


def spacings(h: float | tuple[float, ...], face: str, ndim: int) -> tuple[float, ...]:
    """Voxel edges in the oriented order (`oriented`): the normal's first, then the others in array order; `h` one
    edge (a run's cubic cells) or one per axis in array order ([dz,] dy, dx: a confocal stack's voxels)."""
    edges = (float(h),) * ndim if np.ndim(h) == 0 else tuple(float(e) for e in h)  # type: ignore[union-attr]
    axis = normal_axis(face, ndim)
    return (edges[axis], *(e for a, e in enumerate(edges) if a != axis))


def _columns(voxels: np.ndarray, h: float) -> np.ndarray:
    """Per column normal to the substratum: the top of its topmost biofilm voxel above the substratum (µm)."""
    n = voxels.shape[0]
    topmost = n - np.argmax(voxels[::-1], axis=0)
    return np.where(voxels.any(axis=0), topmost * h, 0.0)


def _surface(voxels: np.ndarray, edges: tuple[float, ...]) -> float:
    """Area of the faces between biofilm and background voxels inside the domain: those normal to an axis have
    the other axes' edges as their sides."""
    cell = float(np.prod(edges))
    return sum(int(np.count_nonzero(np.diff(voxels.view(np.int8), axis=axis))) * cell / edges[axis]
               for axis in range(voxels.ndim))


def counted(voxels: np.ndarray, edges: tuple[float, ...]) -> dict[str, float]:
    """COMSTAT's six observables of boolean biofilm voxels, oriented (`oriented`: the substratum's layer first),
    of `edges` µm (`spacings`); units as `substratum.QUANTITIES`.  One code for a run's cells and a lab's stack."""
    voxels = np.asarray(voxels, dtype=bool)
    area = float(np.prod([n * e for n, e in zip(voxels.shape[1:], edges[1:])]))
    volume = float(np.count_nonzero(voxels)) * float(np.prod(edges))
    thickness = _columns(voxels, edges[0])
    mean = float(thickness.mean())
    return {
        "biomass": volume / area,
        "mean_thickness": mean,
        "max_thickness": float(thickness.max()),
        "roughness": float(np.mean(np.abs(thickness - mean)) / mean) if mean > 0 else float("nan"),
        "coverage": float(voxels[0].mean()),
        "surface_to_biovolume": _surface(voxels, edges) / volume if volume > 0 else float("nan"),
    }


def voxel_observables(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> dict[str, float]:
    """COMSTAT's six observables counted on a run's cells (module docstring), each cell a voxel of edge h."""
    return counted(on_substratum(phi, face) >= threshold, spacings(h, face, phi.ndim))
