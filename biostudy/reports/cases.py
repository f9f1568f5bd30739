"""A study's combined dataset (study.nc) as a list of cases: parameter values, design positions, statuses.

Grid sweeps have one dimension per swept key, zip sweeps and sampled designs a
`case` dimension; the sensitivity estimators and the pictures of a study want
one row per case in the order the cases were planned (a design's row order),
with each parameter's position in the design's unit cube and whether it varies
on a log scale.  A swept key whose values are not numbers (a consumption law,
a grid shape) is a categorical parameter: its values are coded 0, 1, ... in
the order the study lists them (`categories` keeps the labels).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from ..inputs.keys import dimension
from ..plans.designs import Sample, from_attrs


@dataclass
class Cases:
    """A study flattened to a list of cases: parameter values, unit-cube positions, statuses."""

    ids: list[str]
    parameters: dict[str, np.ndarray]  # name in study.nc -> value per case
    unit: dict[str, np.ndarray]  # position in the design's unit cube (sample designs), else rank scaled
    status: np.ndarray
    dims: list[str]  # the study's case dimensions (case, or the grid's swept dimensions)
    design: Sample | None
    log: dict[str, bool] = field(default_factory=dict)
    categories: dict[str, list[str]] = field(default_factory=dict)  # categorical parameter -> its labels, by code

    def values(self, da: xr.DataArray) -> np.ndarray:
        """A variable of study.nc as one row per case (other dimensions kept after it)."""
        da = da.transpose(*self.dims, ...)
        return da.values.reshape(-1, *da.shape[len(self.dims):])


def cases_of(ds: xr.Dataset) -> Cases:
    """The study's cases in the order they were planned (a design's row order)."""
    design = from_attrs(ds.attrs)
    categories = {}
    if "case" in ds.dims:
        dims = ["case"]
        names = [dimension(k) for k in _keys(ds)]
        parameters = {n: _numbers(ds[n].values, n, categories) for n in names}
    else:
        dims = [d.strip() for d in str(ds.attrs.get("sweep_dimensions", "")).split(",") if d.strip()]
        if not dims or not all(d in ds.dims for d in dims):
            raise ValueError("not a study's combined dataset (no case dimension, no sweep_dimensions)")
        codes = [_numbers(ds[d].values, d, categories) for d in dims]
        grids = np.meshgrid(*codes, indexing="ij")
        parameters = {d: g.ravel() for d, g in zip(dims, grids)}
    size = int(np.prod([ds.sizes[d] for d in dims]))
    flat = Cases([], parameters, {}, np.array([]), dims, design, categories=categories)
    flat.ids = [str(v) for v in (flat.values(ds["case_id"]) if "case_id" in ds else range(size))]
    flat.status = flat.values(ds["status"]).astype(str) if "status" in ds else np.full(size, "done")
    if design is not None:
        for key, name in zip(design.keys, parameters):
            rng = design.ranges[key]
            flat.unit[name] = rng.unit(parameters[name])
            flat.log[name] = rng.scale == "log"
    else:
        for name, values in parameters.items():
            if name in categories:
                flat.log[name] = False
                continue
            positive = values[np.isfinite(values)]
            flat.log[name] = bool(positive.size and positive.min() > 0 and positive.max() / positive.min() >= 20)
    return flat


def _keys(ds: xr.Dataset) -> list[str]:
    return [k.strip() for k in str(ds.attrs.get("sweep_keys", ds.attrs.get("sample_keys", ""))).split(",")
            if k.strip()]


def _numbers(values: np.ndarray, name: str, categories: dict[str, list[str]]) -> np.ndarray:
    """A parameter's values as floats; text values as codes 0, 1, ... in the order they first appear (their
    labels go into `categories`)."""
    if values.dtype.kind in "biuf":
        return np.asarray(values, dtype=float)
    labels = [str(v) for v in values]
    order = list(dict.fromkeys(labels))
    categories[name] = order
    return np.array([order.index(label) for label in labels], dtype=float)
