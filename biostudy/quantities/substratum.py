"""Observables on the substratum as experimenters measure them (COMSTAT), computed sub-cell.

COMSTAT (Heydorn et al. 2000, Microbiology 146:2395) measures a confocal stack of a biofilm on a
substratum; BiofilmQ (Hartmann et al. 2021, Nat. Microbiol. 6:151) uses the same definitions.  What is
relied on here, as those papers define it on a binary voxel stack (biomass / background) -- a summary
from the literature, not re-read from the papers' text when this was written:

* biomass: biomass voxels x voxel volume / substratum area (µm³/µm²),
* thickness at a point of the substratum: the height of the topmost biomass voxel in that column
  (pores and voids below it ignored); mean and maximum thickness over all columns, empty ones
  included as zero,
* roughness coefficient Ra* = (1/N) sum_i |L_i - L̄| / L̄ over the N columns' thicknesses L_i,
* substratum coverage: the fraction of the first layer (the image at the substratum) that is biomass,
* surface to biovolume ratio: the biomass's surface exposed to the background over its volume.

Here biofilm is phi >= `threshold` (0.5, the run's own biofilm_volume threshold), obstacle cells (NaN)
are not biofilm, and the substratum is a face of the domain ("x-" ... "z+", x the last array axis).
Every observable is sub-cell: it changes continuously as phi does, not in steps of one cell, because it
is fitted by least squares with finite-difference Jacobians (issue 18: a volume counting cells moved in
steps and put a fit seven standard errors from the truth).  How, and what differs from COMSTAT:

* The biofilm is the region where the piecewise-linear interpolant of phi between cell centres is
  >= threshold, bounded by the phi = threshold level set: marching cubes (3-D) or marching squares
  (2-D) on the field padded by one layer of ghost cells.  Along the substratum's normal the ghosts
  continue phi linearly from the two nearest layers (so a thinning film keeps thinning smoothly to
  zero instead of vanishing as a half cell); across the side walls they mirror it (the level set meets a
  side wall at a right angle, as under a zero-gradient condition, so a wall adds no surface).  An outer
  layer below the threshold closes the level set outside the domain.
* Biovolume is the volume inside that closed level set and inside the domain, from the divergence
  theorem: V = ∮ z n_z dA over the closed level set, z the height above the substratum held between 0
  and the opposite face's height (`LevelSet.volume_below`).  It is the volume of the marching-cubes
  polyhedron, so exact wherever the level set is planar within each cell (a flat slab, a vertical wall,
  a tilted plane) and second order in h for a curved one; a cell count is not used anywhere.
* Thickness is COMSTAT's topmost point, per column from the linear crossing along the column
  (`thickness_profile`, as `biostudy.measures.top`).  Its mean and roughness are integrals over the
  substratum of the height map L(x, y) of the level set of the *filled* field (every cell raised to the
  largest phi above it in its column, so pores and overhangs are filled as COMSTAT ignores them),
  not sums over column centres: a colony whose side wall is vertical otherwise gains a whole column's
  height at once when the wall passes a column centre.  COMSTAT's column sums are the midpoint rule of
  these integrals; for columns of equal height they agree, at a step between columns the height map
  ramps across one cell, so Ra* of a staircase is smaller than the column formula's.
* Coverage is the area fraction of the first cell layer's plane (the cell centres next to the
  substratum) inside the level set: the layer's own interpolated field, sub-cell.
* The surface is the level set inside the domain: the biofilm-liquid interface only.  Where the biofilm
  meets the substratum, a side wall or the opposite face it has no surface (COMSTAT counts surface
  exposed to the background, and a hemisphere then has 3/r).  Where it meets an obstacle it has
  (an obstacle cell is not biomass, as COMSTAT cannot tell it from the background).
* Areas are of the whole face (obstacle footprints included): the field of view.

Continuity: the level set's vertices move continuously with phi, so every observable is continuous in
phi except where phi is exactly flat at the threshold over a cell (a film of uniform phi = threshold)
and, in 3-D, where marching cubes (Lewiner) changes its triangulation of a cell whose corners form a
saddle at the threshold: two pieces of biofilm joining inside one cell (measured for two domes merging:
a jump of 0.04 h³ in biovolume, against h³ per cell for a cell count).  Marching squares resolves
saddles by a fixed rule (fully_connected="low"), so 2-D has no such jump.  `thickness_profile` and
`max_thickness` are continuous except where a column's profile is flat at the threshold.

All functions take phi in the solver's array order ((z, y, x) in 3-D, (y, x) in 2-D), the cubic cells'
size h (µm), the substratum face and the threshold; `substratum_observables` computes all at once.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from skimage.measure import find_contours, marching_cubes

from solver.problem import face_problem
from solver.series import BIOFILM_THRESHOLD as THRESHOLD  # biofilm is phi >= 0.5, as the run's own biofilm_volume

from ..inputs.substratum_face import normal_axis


def on_substratum(phi: np.ndarray, face: str) -> np.ndarray:
    """phi with the substratum's normal as the first axis, index 0 next to the substratum, obstacles (NaN) as 0.

    The remaining axes keep their order (in 3-D for "z-": (z, y, x); for "x-": (x, z, y))."""
    phi = np.asarray(phi, dtype=float)
    if phi.ndim not in (2, 3):
        raise ValueError(f"phi must be a 2-D or 3-D field, not {phi.ndim}-D")
    problem = face_problem(face, phi.ndim)
    if problem:
        raise ValueError(problem)
    field = np.moveaxis(np.nan_to_num(phi, nan=0.0), normal_axis(face, phi.ndim), 0)
    return field[::-1] if face[1] == "+" else field


def substratum_area(phi: np.ndarray, h: float, face: str) -> float:
    """Area of the substratum face (µm²; 2-D: its width, µm), obstacle footprints included."""
    field = on_substratum(phi, face)
    return float(np.prod(field.shape[1:])) * h ** (field.ndim - 1)


# ---- per column ---------------------------------------------------------------------------------------------

def _continued(field: np.ndarray) -> np.ndarray:
    """The field with one ghost layer beyond each end of its first (normal) axis, phi continued linearly from the
    two nearest layers (held constant when there is only one layer)."""
    if field.shape[0] == 1:
        below = above = field[0]
    else:
        below, above = 2.0 * field[0] - field[1], 2.0 * field[-1] - field[-2]
    return np.concatenate([below[None], field, above[None]])


def thickness_profile(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> np.ndarray:
    """COMSTAT's thickness per column (µm): the height above the substratum of the column's topmost biofilm point.

    One value per column normal to the substratum (an array of the face's shape).  Along the column phi is
    interpolated linearly between cell centres and continued linearly to the two faces; the topmost point is the
    crossing of the threshold above the topmost node with phi >= threshold (as `biostudy.measures.top`, which
    holds phi constant over the half cell next to a face instead), at most the opposite face.  0 where the column
    has no biofilm.  COMSTAT counts whole voxels; this is sub-cell along the column (a slab whose phi crosses 0.5
    at 3.3 µm is 3.3 µm thick), but a column whose phi is uniform along it joins or leaves at once when that
    value crosses the threshold."""
    field = on_substratum(phi, face)
    n = field.shape[0]
    values = _continued(field)
    heights = (np.arange(n + 2) - 0.5) * h  # ghost centres at -h/2 and (n + 1/2) h
    inside = values >= threshold
    last = n + 1 - np.argmax(inside[::-1], axis=0)  # topmost node inside, per column
    above = np.minimum(last + 1, n + 1)
    a = np.take_along_axis(values, last[None], axis=0)[0]
    b = np.take_along_axis(values, above[None], axis=0)[0]
    at_end = last == n + 1
    fraction = np.where(at_end, 0.0, (a - threshold) / np.where(at_end, 1.0, a - b))  # a >= threshold > b
    top = heights[last] + fraction * h
    return np.where(inside.any(axis=0), np.clip(top, 0.0, n * h), 0.0)


def max_thickness(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's maximum thickness (µm): the largest `thickness_profile`; 0 without biofilm."""
    return float(np.max(thickness_profile(phi, h, face, threshold)))


# ---- the level set ------------------------------------------------------------------------------------------

def _mean_positive(f: np.ndarray) -> np.ndarray:
    """Mean of max(f, 0) over each piece (segment or triangle) on which f is linear; rows: f at its corners."""
    f = -np.sort(-f, axis=1)  # descending
    with np.errstate(divide="ignore", invalid="ignore"):
        if f.shape[1] == 2:
            a, b = f.T
            return np.where(b >= 0, (a + b) / 2, np.where(a <= 0, 0.0, a * a / (2 * (a - b))))
        a, b, c = f.T
        one = a**3 / (3 * (a - b) * (a - c))  # only a > 0: the corner triangle at a
        two = (a + b + c) / 3 - c**3 / (3 * (a - c) * (b - c))  # only c < 0: the mean plus the cut-off part
        return np.where(c >= 0, (a + b + c) / 3, np.where(a <= 0, 0.0, np.where(b <= 0, one, two)))


def _share_positive(f: np.ndarray) -> np.ndarray:
    """Fraction of each piece (segment or triangle) where f > 0, f linear on it; rows: f at its corners."""
    f = -np.sort(-f, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        if f.shape[1] == 2:
            a, b = f.T
            return np.where(b >= 0, 1.0, np.where(a <= 0, 0.0, a / (a - b)))
        a, b, c = f.T
        one = a * a / ((a - b) * (a - c))
        two = 1.0 - c * c / ((a - c) * (b - c))
        return np.where(c >= 0, 1.0, np.where(a <= 0, 0.0, np.where(b <= 0, one, two)))


@dataclass(frozen=True)
class LevelSet:
    """The phi = threshold level set as pieces (triangles in 3-D, segments in 2-D), closed outside the domain.

    heights: (pieces, corners) each corner's height above the substratum (µm), linear over the piece.
    weight: each piece's share inside the side walls: 1 inside, 1/2 in a ghost cell beyond one side wall
        (there the level set is mirrored, normal to the wall, so exactly half of it is inside), 1/4 at an edge,
        0 beyond (where the level set is closed).
    size: area (3-D, µm²) or length (2-D, µm) of each piece.
    normal: size times the component, away from the substratum, of the normal pointing out of the biofilm.
    top: the domain's height over the substratum (µm), where the opposite face is."""

    heights: np.ndarray
    weight: np.ndarray
    size: np.ndarray
    normal: np.ndarray
    top: float

    def surface(self) -> float:
        """Area (2-D: length) of the level set inside the domain: the biofilm's surface exposed to the liquid."""
        inside = _share_positive(self.heights) - _share_positive(self.heights - self.top)
        return float(np.sum(self.weight * self.size * inside))

    def volume_below(self, height: float) -> float:
        """Volume (2-D: area) of biofilm inside the domain below `height` above the substratum (at most top).

        Divergence theorem with F = min(max(z, 0), height) e_z, whose divergence is 1 in 0 < z < height and 0
        elsewhere: the volume is ∮ F_z n_z dA over the closed level set; F vanishes on the substratum and below
        it, is tangential to the side walls, and is constant above `height`, where the level set closes the
        biofilm's cross-section there."""
        height = min(height, self.top)
        clipped = _mean_positive(self.heights) - _mean_positive(self.heights - height)
        return float(np.sum(self.weight * self.normal * clipped))

    def section(self, height: float) -> float:
        """Area (2-D: length) of the biofilm's cross-section at `height`: the projected area of the level set
        above it (the closed surface above the plane projects onto the plane as its cross-section)."""
        return float(np.sum(self.weight * self.normal * _share_positive(self.heights - height)))


def level_set(field: np.ndarray, h: float, threshold: float = THRESHOLD) -> LevelSet:
    """The phi = threshold level set of a field on the substratum (as `on_substratum` gives it).

    Padded by ghost cells (linear continuation along the normal, mirror across the side walls) and then by one
    layer below the threshold that closes it; marching cubes (skimage, Lewiner) in 3-D, marching squares
    (`find_contours`) in 2-D, both placing vertices by linear interpolation between cell centres."""
    n = field.shape
    padded = np.pad(_continued(field), [(0, 0)] + [(1, 1)] * (field.ndim - 1), mode="edge")
    padded = np.pad(padded, 1, constant_values=threshold - 1.0)
    if not (padded >= threshold).any():
        empty = np.zeros((0, field.ndim))
        return LevelSet(empty, np.zeros(0), np.zeros(0), np.zeros(0), n[0] * h)
    if field.ndim == 3:  # skimage works in float32 (up to 3.4e38): a larger phi would make its vertices NaN
        verts, faces, _, _ = marching_cubes(np.clip(padded, -FLOAT32_SAFE, FLOAT32_SAFE), threshold)  # index units
        corners = _on_edges(verts, padded, threshold)[faces]  # (triangles, 3, 3)
        # skimage winds the triangles with the biofilm (values above the level) on the side of this cross product
        vector = -0.5 * np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        size, normal = np.linalg.norm(vector, axis=1) * h**2, vector[:, 0] * h**2
    else:
        lines = find_contours(padded, threshold, positive_orientation="high")
        corners = np.concatenate([np.stack([c[:-1], c[1:]], axis=1) for c in lines])  # (segments, 2, 2)
        step = corners[:, 1] - corners[:, 0]
        # biofilm on the left of each step: the outward normal times the length is (step_x, -step_z) in (z, x)
        size, normal = np.linalg.norm(step, axis=1) * h, step[:, 1] * h
    centre = corners.mean(axis=1)
    weight = np.ones(len(corners))
    for axis in range(1, field.ndim):  # the side walls
        share = np.r_[0.0, 0.5, np.ones(n[axis] - 1), 0.5, 0.0]  # per cell of the padded grid's dual cells
        cube = np.clip(np.floor(centre[:, axis]).astype(int), 0, n[axis] + 2)
        weight *= share[cube]
    heights = (corners[..., 0] - 1.5) * h  # the substratum lies half-way between padded indices 1 and 2
    return LevelSet(heights, weight, size, normal, n[0] * h)


FLOAT32_SAFE = 1e30  # marching cubes sees phi clipped to this: its edges and crossings are the same in float32


def _on_edges(verts: np.ndarray, padded: np.ndarray, threshold: float) -> np.ndarray:
    """Marching cubes' vertices in double precision (skimage returns float32, whose rounding would be noise in a
    finite-difference Jacobian): each lies on a grid edge, at the linear crossing recomputed from the field
    (unclipped: a huge phi beside a small one puts the crossing right beside the small one)."""
    p = verts.astype(float)
    nearest = np.rint(p)
    axis = np.argmax(np.abs(p - nearest), axis=1)  # the edge's direction: the one coordinate between nodes
    rows = np.arange(len(p))
    low = nearest.astype(int)
    low[rows, axis] = np.clip(np.floor(p[rows, axis]).astype(int), 0, np.array(padded.shape)[axis] - 2)
    high = low.copy()
    high[rows, axis] += 1
    a, b = padded[tuple(low.T)], padded[tuple(high.T)]
    crossing = (a - threshold) * (b - threshold) <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(crossing & (a != b), (threshold - a) / (b - a), np.nan)
    exact = np.isfinite(t)  # otherwise (a vertex at a node, rounded to the other side) keep skimage's position
    p[rows[exact], axis[exact]] = low[rows[exact], axis[exact]] + t[exact]
    return p


def _filled(field: np.ndarray) -> np.ndarray:
    """Every cell raised to the largest phi above it in its column: the biofilm with pores and overhangs filled,
    whose level set's height over each point of the substratum is the COMSTAT thickness there."""
    return np.maximum.accumulate(field[::-1], axis=0)[::-1]


# ---- the observables ----------------------------------------------------------------------------------------

def biovolume(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """Biofilm volume (µm³; 2-D: area, µm²): inside the interpolated level set phi = threshold (not a cell count);
    exact for a slab, continuous in phi."""
    return level_set(on_substratum(phi, face), h, threshold).volume_below(np.inf)


def biomass(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's biomass: biovolume per substratum area (µm³/µm² = µm; 2-D: µm²/µm = µm).

    COMSTAT counts biomass voxels; here the volume inside the interpolated level set (`biovolume`)."""
    return biovolume(phi, h, face, threshold) / substratum_area(phi, h, face)


def mean_thickness(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's mean thickness (µm): the biofilm's top height above the substratum averaged over the whole
    substratum, bare parts included as zero.

    COMSTAT averages the columns' thicknesses; here the height map of the filled biofilm's level set is integrated
    over the substratum (its volume over the substratum's area), which is continuous when a vertical side wall
    moves across a column centre.  Equal to the mean of `thickness_profile` where the level set's top runs
    straight from column top to column top (a slab; a staircase of columns whose phi falls linearly with height);
    at a vertical side wall it differs, as the column mean moves only when the wall passes a column centre.
    Equal to `biomass` when the biofilm has no pores or overhangs."""
    field = on_substratum(phi, face)
    return level_set(_filled(field), h, threshold).volume_below(np.inf) / substratum_area(phi, h, face)


def roughness(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's roughness coefficient Ra* = mean |L - L̄| / L̄ (dimensionless) of the thickness L over the
    substratum, L̄ the mean thickness; NaN without biofilm (L̄ = 0).

    COMSTAT averages over columns; here over the height map L(x, y) of the filled biofilm (as `mean_thickness`).
    Since L - L̄ averages to zero, mean |L - L̄| = 2 mean (L - L̄)+, and the integral of (L - L̄)+ is the filled
    biofilm's volume above the height L̄: Ra* = 2 (V - V(below L̄)) / V."""
    filled = level_set(_filled(on_substratum(phi, face)), h, threshold)
    return _roughness(filled, substratum_area(phi, h, face))


def _roughness(filled: LevelSet, area: float) -> float:
    volume = filled.volume_below(np.inf)
    if volume <= 0:
        return float("nan")
    return 2.0 * (volume - filled.volume_below(volume / area)) / volume


def coverage(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's substratum coverage (dimensionless, 0 to 1): the fraction of the first cell layer on the
    substratum that is biofilm.

    COMSTAT counts the first image's biomass pixels; here the area fraction of the first layer's plane (through
    its cell centres, h/2 above the substratum) where the interpolated phi >= threshold: the cross-section of the
    level set there (in 2-D the fraction of the layer's line), sub-cell.  Obstacle cells count as not biofilm."""
    field = on_substratum(phi, face)
    return level_set(field, h, threshold).section(h / 2) / substratum_area(phi, h, face)


def surface_area(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """Area (µm²; 2-D: length, µm) of the biofilm's surface exposed to the liquid: the phi = threshold level set
    inside the domain (marching cubes / squares), without the faces where the biofilm meets the substratum, the
    side walls or the opposite face; the biofilm's contact with obstacles is included."""
    return level_set(on_substratum(phi, face), h, threshold).surface()


def surface_to_biovolume(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> float:
    """COMSTAT's surface to biovolume ratio (µm²/µm³ = µm⁻¹; 2-D: µm/µm² = µm⁻¹): surface_area/biovolume.

    COMSTAT counts exposed voxel faces (a staircase, which overestimates a smooth surface's area); here the
    level set's area, so a hemisphere of radius r on the substratum tends to 3/r.  NaN without biofilm; 0 when
    the biofilm fills the domain."""
    surface = level_set(on_substratum(phi, face), h, threshold)
    return _ratio(surface.surface(), surface.volume_below(np.inf))


def _ratio(surface: float, volume: float) -> float:
    return surface / volume if volume > 0 else float("nan")


def substratum_observables(phi: np.ndarray, h: float, face: str, threshold: float = THRESHOLD) -> dict[str, float]:
    """All of `QUANTITIES` for one field, the level sets computed once (what the observables registry calls)."""
    field = on_substratum(phi, face)
    area = substratum_area(phi, h, face)
    biofilm = level_set(field, h, threshold)
    filled = level_set(_filled(field), h, threshold)
    volume = biofilm.volume_below(np.inf)
    return {
        "biomass": volume / area,
        "mean_thickness": filled.volume_below(np.inf) / area,
        "max_thickness": max_thickness(phi, h, face, threshold),
        "roughness": _roughness(filled, area),
        "coverage": biofilm.section(h / 2) / area,
        "surface_to_biovolume": _ratio(biofilm.surface(), volume),
    }


@dataclass(frozen=True)
class Quantity:
    """One substratum observable: its name, udunits units and long name, and the function computing it."""

    name: str
    units: str
    long_name: str
    compute: Callable[..., float]


# units reduced: µm³/µm² (2-D µm²/µm) is "um", µm²/µm³ (2-D µm/µm²) is "um^-1" (udunits and plain pint read it)
QUANTITIES: dict[str, Quantity] = {q.name: q for q in (
    Quantity("biomass", "um", "biovolume per substratum area (COMSTAT biomass; 2-D: biofilm area per substratum "
             "width)", biomass),
    Quantity("mean_thickness", "um", "mean biofilm thickness over the substratum, bare substratum as zero "
             "(COMSTAT)", mean_thickness),
    Quantity("max_thickness", "um", "maximum biofilm thickness above the substratum (COMSTAT)", max_thickness),
    Quantity("roughness", "1", "roughness coefficient Ra* of the biofilm thickness (COMSTAT)", roughness),
    Quantity("coverage", "1", "fraction of the substratum's first cell layer covered by biofilm (COMSTAT "
             "substratum coverage)", coverage),
    Quantity("surface_to_biovolume", "um^-1", "biofilm surface exposed to the liquid per biovolume (COMSTAT; "
             "2-D: perimeter per area)", surface_to_biovolume),
)}
