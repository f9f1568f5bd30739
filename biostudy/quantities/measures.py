"""What accuracy reports measure on datasets: fields on a common grid, a front, observed orders.

* `restrict`: a field on a grid refined by an integer factor, averaged over
  the fine cells inside each coarse cell (the finite-volume restriction: it
  keeps cell averages, so fields of different resolutions compare on the
  coarsest grid).  Obstacle cells (NaN) are left out of the averages.
* `field_errors`: L1 and L2 norms of a difference per unit volume of open cells.
* `front_position`: how far the biofilm reaches from where it started toward
  the nutrient: along the ray from the initial biofilm's centroid to the
  centroid of the held-nutrient region, the last point where phi (linearly
  interpolated between cell centres) is still >= 0.5, in µm from the
  starting centroid.  Sub-cell accurate, so it converges under refinement.
* Dense quantities, per output time (what "a dense colony grows tall" means):
  `volume` (of phi >= a level: 0.5 the biofilm, 0.8 the dense biofilm, the paper's isosurface level, Figs. 3 and 10),
  `height` (the highest point of phi >= 0.5 along an axis, sub-cell), `reach`
  (the largest distance of a phi >= 0.5 cell centre from an axis through the
  initial colony) and `nutrient_minimum` (where c is lowest, and phi there).
* Run summaries, per output time: `front_advance` (the front position's gain
  since the start) and `stress_extremes` (the largest compression and tension
  of p).  `biostudy.observables` names them.
* `observed_order`: the slope of log(error) against log(h or dt).
"""
from __future__ import annotations

import numpy as np
import xarray as xr
from scipy.ndimage import map_coordinates

from solver.output import on_output_times
from solver.series import BIOFILM_THRESHOLD

THRESHOLD = BIOFILM_THRESHOLD  # the biofilm's extent, as the run's own biofilm_volume counts it
DENSE = 0.8


def restrict(field: np.ndarray, factor: int) -> np.ndarray:
    """Average `factor`^ndim blocks of fine cells into coarse cells, ignoring NaN (obstacles)."""
    if factor == 1:
        return field
    shape = []
    for n in field.shape:
        if n % factor:
            raise ValueError(f"cannot restrict {field.shape} by {factor}")
        shape += [n // factor, factor]
    blocks = field.reshape(shape)
    axes = tuple(range(1, 2 * field.ndim, 2))
    if not np.isnan(field).any():
        return blocks.mean(axis=axes)
    finite = np.isfinite(blocks)  # a coarse cell of obstacle cells only stays NaN (no warning: it is meant)
    count = finite.sum(axis=axes)
    total = np.where(finite, blocks, 0.0).sum(axis=axes)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def field_errors(field: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """(L1, L2) of field - reference, per open cell: mean |e| and sqrt(mean e^2)."""
    diff = (field - reference)[np.isfinite(field) & np.isfinite(reference)]
    if diff.size == 0:
        return float("nan"), float("nan")
    return float(np.mean(np.abs(diff))), float(np.sqrt(np.mean(diff**2)))


def centroid(mask: np.ndarray, centres: list[np.ndarray]) -> np.ndarray | None:
    """Centre (µm) of a cell mask, in the mask's axis order given by `centres`; None for an empty mask."""
    if not mask.any():
        return None
    grids = np.meshgrid(*centres, indexing="ij")  # the mask's axis order
    return np.array([g[mask].mean() for g in grids])


def front_position(ds: xr.Dataset, time_index: int = -1) -> float:
    """Distance (µm) from the initial biofilm's centroid to the farthest phi >= 0.5 toward the source."""
    centres = [ds[d].values for d in _cell_dims(ds)]
    h = spacing(ds)
    start = centroid(ds["phi"].isel(time=0).values >= THRESHOLD, centres)
    source = centroid(ds["nutrient_source"].values.astype(bool), centres)
    if start is None or source is None or np.allclose(start, source):
        return float("nan")
    direction = (source - start) / np.linalg.norm(source - start)
    phi = np.nan_to_num(ds["phi"].isel(time=time_index).values, nan=0.0)
    low = np.array([c[0] for c in centres])
    high = np.array([c[-1] for c in centres])
    # the ray until it leaves the box of cell centres
    with np.errstate(divide="ignore", invalid="ignore"):
        backward = np.where(direction < 0, (low - start) / direction, np.inf)
        exits = np.where(direction > 0, (high - start) / direction, backward)
    length = float(np.min(exits))
    s = np.arange(0.0, length + 1e-12, h / 8.0)
    points = start[:, None] + direction[:, None] * s[None, :]
    index = (points - low[:, None]) / h
    values = map_coordinates(phi, index, order=1, mode="nearest")
    inside = values >= THRESHOLD
    if not inside.any():
        return 0.0
    last = int(np.flatnonzero(inside)[-1])
    if last + 1 >= s.size:
        return float(s[-1])
    a, b = values[last], values[last + 1]
    return float(s[last] + (a - THRESHOLD) / (a - b) * (s[last + 1] - s[last]))


def _cell_dims(ds: xr.Dataset) -> list[str]:
    return [d for d in ("z", "y", "x") if d in ds.dims]


def spacing(ds: xr.Dataset) -> float:
    """The cell size (µm): recorded, or from any axis with two cells or more (cells are cubes)."""
    if "grid_spacing" in ds.attrs:
        return float(ds.attrs["grid_spacing"])
    centres = next(ds[d].values for d in _cell_dims(ds) if ds.sizes[d] > 1)
    return float(centres[1] - centres[0])


RECORDED = {THRESHOLD: "biofilm_volume", DENSE: "dense_volume"}  # the observables a run's dataset keeps of these


def volume(ds: xr.Dataset, level: float = DENSE) -> np.ndarray:
    """Volume (µm³; 2-D: µm² per µm of thickness) of cells with phi >= level, per output time."""
    dims = _cell_dims(ds)
    return (ds["phi"] >= level).sum(dims).values * spacing(ds) ** len(dims)


def kept_volume(ds: xr.Dataset, level: float) -> np.ndarray:
    """`volume`, read from the run's own observable where the dataset keeps it (a streamed run's phi is read from
    disk again for every pass over it)."""
    name = RECORDED.get(level)
    if name in ds.data_vars and ds[name].dims == ("time",):
        return np.asarray(ds[name].values, dtype=float)
    return volume(ds, level)


def phi_max(ds: xr.Dataset) -> np.ndarray:
    """Largest phi per output time."""
    return ds["phi"].max(_cell_dims(ds)).values


def height(ds: xr.Dataset, axis: str, level: float = THRESHOLD) -> np.ndarray:
    """Highest point (µm) along `axis` where phi >= level, per output time; NaN where no cell reaches level.

    In every column along the axis the crossing above the highest cell with phi >= level is placed by linear
    interpolation between the two cell centres (at the cell's upper face when it is the last cell)."""
    dims = _cell_dims(ds)
    centres = ds[axis].values
    h = spacing(ds)
    phi = np.moveaxis(np.nan_to_num(ds["phi"].values, nan=0.0), dims.index(axis) + 1, -1)  # (time, ..., axis)
    out = np.full(phi.shape[0], np.nan)
    for t, field in enumerate(phi):
        inside = field >= level
        columns = inside.any(axis=-1)
        if not columns.any():
            continue
        last = field.shape[-1] - 1 - np.argmax(inside[..., ::-1], axis=-1)  # highest index >= level per column
        last = last[columns]
        column = field[columns]
        a = np.take_along_axis(column, last[:, None], axis=-1)[:, 0]
        nxt = np.take_along_axis(column, np.minimum(last + 1, field.shape[-1] - 1)[:, None], axis=-1)[:, 0]
        at_end = last == field.shape[-1] - 1
        fraction = np.where(at_end, 0.5, (a - level) / np.where(at_end, 1.0, a - nxt))
        out[t] = float(np.max(centres[last] + fraction * h))
    return out


def top(ds: xr.Dataset, axis: str) -> float:
    """The domain's upper face along `axis` (µm): a `height` equal to it is saturated, a lower bound (the
    biofilm reaches the top of the box and may have grown on, out of it)."""
    return float(ds[axis].values[-1] + 0.5 * spacing(ds))


def reach(ds: xr.Dataset, axis: str, level: float = THRESHOLD) -> np.ndarray:
    """Largest distance (µm) of a cell centre with phi >= level from the line along `axis` through the centroid
    of the initial phi >= level, per output time (the radius of a colony's footprint)."""
    dims = _cell_dims(ds)
    centres = [ds[d].values for d in dims]
    start = centroid(ds["phi"].isel(time=0).values >= level, centres)
    grids = np.meshgrid(*centres, indexing="ij")
    across = sum((g - m) ** 2 for d, g, m in zip(dims, grids, start) if d != axis) ** 0.5
    return np.array([np.max(across[phi >= level]) if (phi >= level).any() else np.nan for phi in ds["phi"].values])


def nutrient_minimum(ds: xr.Dataset) -> dict[str, np.ndarray]:
    """Where c is lowest per output time: its coordinates (µm, one array per axis), the value and phi there."""
    dims = _cell_dims(ds)
    out = {d: [] for d in dims} | {"c": [], "phi": []}
    for c, phi in zip(ds["c"].values, ds["phi"].values):
        index = np.unravel_index(np.nanargmin(c), c.shape)
        for d, i in zip(dims, index):
            out[d].append(float(ds[d].values[i]))
        out["c"].append(float(c[index]))
        out["phi"].append(float(phi[index]))
    return {k: np.array(v) for k, v in out.items()}


def front_advance(ds: xr.Dataset) -> np.ndarray:
    """How far (µm) the front has moved toward the nutrient source since the first output, per output time."""
    positions = np.array([front_position(ds, i) for i in range(ds.sizes["time"])])
    return positions - positions[0]


def stress_extremes(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(largest compression -min p, largest tension max p) in Pa per output time; NaN where p was not solved."""
    dims = _cell_dims(ds)
    p = on_output_times(ds)["p"]
    solved = p.notnull().any(dims).values
    low = p.min(dims, skipna=True).values
    high = p.max(dims, skipna=True).values
    return np.where(solved, -low, np.nan), np.where(solved, high, np.nan)


def observed_order(sizes, errors) -> float:
    """Least-squares slope of log(error) against log(size); NaN when fewer than two usable points."""
    sizes, errors = np.asarray(sizes, float), np.asarray(errors, float)
    ok = (errors > 0) & np.isfinite(errors) & (sizes > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(sizes[ok]), np.log(errors[ok]), 1)[0])
