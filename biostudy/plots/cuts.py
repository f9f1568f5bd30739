"""Plane cuts through a 3-D run: where the plane lies, and the fields sampled on it.

The paper's pictures of the inside of the cube (Tables 3 and 5) are a
*diagonal cut*: the vertical plane through the domain centre that contains the
horizontal direction toward the nutrient source, drawn with the source at the
top right.  Here the direction comes from the centroid of the
`nutrient_source` mask; when the source has no horizontal offset from the
centre (a bottom layer, as in the agar scene) or there is none, the plane is
the one through the xy-diagonal of the box ('xy-diagonal' asks for that plane
whatever the source).  Axis-aligned cuts ("x=10", "z=5.5", µm) are planes of
constant x, y or z.

Fields are cell averages at cell centres; the plane is sampled by trilinear
interpolation between centres (exact for fields linear in x, y, z), and held
constant over the half cell between the outermost centres and the boundary,
which is what the zero-flux boundary of phi and c means.  Obstacle cells
(NaN) are left out of the interpolation weights; a point whose weights lie
mostly in obstacles is NaN, drawn grey.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy import ndimage

from ..quantities.measures import centroid

AXES = ("x", "y", "z")
_AXIS_CUT = re.compile(r"^\s*([xyz])\s*=\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?:um|µm)?\s*$")


@dataclass(frozen=True)
class Plane:
    """A rectangle in the domain: point(s, t) = origin + s * along + t * up, s and t in µm.

    along, up: orthonormal in-plane directions (x, y, z components), drawn right and up.
    s_range, t_range: the part of the plane inside the domain.
    flip_up: draw t growing downward (keeps a source below the centre at the top).
    """

    origin: np.ndarray
    along: np.ndarray
    up: np.ndarray
    s_range: tuple[float, float]
    t_range: tuple[float, float]
    s_label: str
    t_label: str
    title: str
    flip_up: bool = False

    def grid(self, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sample coordinates s (ns,), t (nt,) and their points (nt, ns, 3) in µm, about `step` apart."""
        s = _samples(*self.s_range, step)
        t = _samples(*self.t_range, step)
        points = self.origin + s[None, :, None] * self.along + t[:, None, None] * self.up
        return s, t, points


def _samples(low: float, high: float, step: float) -> np.ndarray:
    return np.linspace(low, high, max(2, int(round((high - low) / step)) + 1))


def cell_axes(ds: xr.Dataset) -> tuple[np.ndarray, ...]:
    """Cell-centre coordinates x, y[, z] (µm) of the axes the run has."""
    return tuple(np.asarray(ds[a].values, dtype=float) for a in AXES if a in ds.dims)


def box(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper corner of the domain (µm), from the cell centres (2 or 3 entries)."""
    centres = cell_axes(ds)
    half = np.array([0.5 * (c[1] - c[0]) if c.size > 1 else 0.5 * float(ds.attrs.get("grid_spacing", 1.0))
                     for c in centres])
    lower = np.array([c[0] for c in centres]) - half
    upper = np.array([c[-1] for c in centres]) + half
    return lower, upper


def source_centroid(ds: xr.Dataset) -> np.ndarray | None:
    """Centre of mass (x, y, z) of the nutrient-source cells, or None without a source."""
    if "nutrient_source" not in ds:
        return None
    mask = ds["nutrient_source"].transpose("z", "y", "x").values.astype(bool)
    centre = centroid(mask, cell_axes(ds)[::-1])  # (z, y, x) like the mask
    return None if centre is None else centre[::-1]


def diagonal_plane(ds: xr.Dataset, toward_source: bool = True) -> Plane:
    """The paper's diagonal cut: vertical, through the centre, toward the nutrient source.

    toward_source=False: always the plane through the xy-diagonal (the paper's Table 5, whose
    source is a whole face).
    """
    lower, upper = box(ds)
    centre = 0.5 * (lower + upper)
    source = source_centroid(ds) if toward_source else None
    offset = None if source is None else (source - centre)[:2]
    toward_source = offset is not None and np.hypot(*offset) > 1e-6 * np.hypot(*(upper - lower)[:2])
    horizontal = offset if toward_source else (upper - lower)[:2]
    horizontal = horizontal / np.hypot(*horizontal)
    along = np.array([horizontal[0], horizontal[1], 0.0])
    # clip the horizontal line through the centre to the box: s in [s_min, s_max]
    s_min, s_max = -np.inf, np.inf
    for axis in (0, 1):
        if abs(along[axis]) > 1e-12:
            ends = sorted(((lower[axis] - centre[axis]) / along[axis], (upper[axis] - centre[axis]) / along[axis]))
            s_min, s_max = max(s_min, ends[0]), min(s_max, ends[1])
    origin = np.array([centre[0], centre[1], 0.0])
    direction = f"({along[0]:.2f}, {along[1]:.2f}, 0)"
    reason = "toward the nutrient source" if toward_source else "along the xy-diagonal"
    flip = bool(toward_source and source[2] < centre[2])
    return Plane(origin=origin, along=along, up=np.array([0.0, 0.0, 1.0]), s_range=(s_min, s_max),
                 t_range=(lower[2], upper[2]), s_label=f"s (µm) from the centre along {direction}",
                 t_label="z (µm), drawn downward" if flip else "z (µm)",
                 title=f"diagonal cut: vertical plane through the centre {reason}", flip_up=flip)


def axis_plane(ds: xr.Dataset, axis: str, value: float) -> Plane:
    """The plane axis = value (µm): x and y cuts show (y or x, z), z cuts show (x, y)."""
    lower, upper = box(ds)
    k = AXES.index(axis)
    if not lower[k] <= value <= upper[k]:
        raise ValueError(f"cut {axis}={value:g} is outside the domain "
                         f"({axis} from {lower[k]:g} to {upper[k]:g} µm)")
    s_axis, t_axis = {"x": ("y", "z"), "y": ("x", "z"), "z": ("x", "y")}[axis]
    unit = np.eye(3)
    origin = np.zeros(3)
    origin[k] = value
    s, t = AXES.index(s_axis), AXES.index(t_axis)
    return Plane(origin=origin, along=unit[s], up=unit[t], s_range=(lower[s], upper[s]),
                 t_range=(lower[t], upper[t]), s_label=f"{s_axis} (µm)", t_label=f"{t_axis} (µm)",
                 title=f"cut {axis} = {value:g} µm")


def plane_for(ds: xr.Dataset, cut: str | None) -> Plane:
    """Parse a cut option: None or 'diagonal' (the paper's cut), 'xy-diagonal', or 'x=10', 'y=4', 'z=5.5' (µm)."""
    if cut is None or cut.strip().lower() == "diagonal":
        return diagonal_plane(ds)
    if cut.strip().lower() == "xy-diagonal":
        return diagonal_plane(ds, toward_source=False)
    match = _AXIS_CUT.match(cut)
    if not match:
        raise ValueError(f"unknown cut {cut!r}; use 'diagonal', 'xy-diagonal' or AXIS=VALUE in µm, "
                         "e.g. 'x=10' or 'z=5.5'")
    return axis_plane(ds, match.group(1), float(match.group(2)))


def _index(centres: tuple[np.ndarray, ...], points: np.ndarray) -> np.ndarray:
    """Points (..., 3) as (x, y, z) in µm -> fractional cell indices (3, ...) in array order z, y, x."""
    index = []
    for axis in (2, 1, 0):
        c = centres[axis]
        step = c[1] - c[0] if c.size > 1 else 1.0
        index.append((points[..., axis] - c[0]) / step)
    return np.stack(index)


def sample(field: np.ndarray, centres: tuple[np.ndarray, ...], points: np.ndarray) -> np.ndarray:
    """Trilinear interpolation of a cell field (z, y, x) at points (..., 3) given as (x, y, z) in µm.

    centres: the cell-centre coordinates x, y, z (uniform spacing along each axis).
    NaN cells carry no weight; where less than half the weight is finite, the result is NaN.
    """
    index = _index(centres, points)
    finite = np.isfinite(field)
    value = ndimage.map_coordinates(np.where(finite, field, 0.0), index, order=1, mode="nearest")
    weight = ndimage.map_coordinates(finite.astype(float), index, order=1, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(weight >= 0.5 - 1e-9, value / weight, np.nan)


def sample_nearest(mask: np.ndarray, centres: tuple[np.ndarray, ...], points: np.ndarray) -> np.ndarray:
    """A cell mask (z, y, x) at points (..., 3): the value of the cell containing each point."""
    index = np.round(_index(centres, points)).astype(int)
    return mask[tuple(np.clip(i, 0, n - 1) for i, n in zip(index, mask.shape))]
