"""What the tables say, as JSON for scripts (`--json`): the same numbers, unrounded.

JSON has no NaN or infinity: a value that is not finite is ``null``
(`plain`), so `json.loads` reads every record strictly; a table shows such a
value as "-" ("inf" where infinite; the dataset keeps it).  A record is a dict
with a "kind" ("run", "study", "dataset", "scenes") and plain values; netCDF
attributes come as they are in the file.
"""
from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..quantities.saturation import SATURATION
from .show import case_columns, scene_title, shown_in_study

if TYPE_CHECKING:
    import xarray as xr


def plain(value: Any) -> Any:
    """JSON's values: numpy scalars and arrays as numbers and lists, NaN and infinities as None."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return str(value)  # a date, a path


def text(record: Any) -> str:
    """The record as strict JSON (no NaN), one value per line for a diff."""
    return json.dumps(plain(record), indent=1, ensure_ascii=False, allow_nan=False)


def run_record(attrs: dict, times: np.ndarray | None, series: list[tuple[str, np.ndarray, dict]]) -> dict:
    """One run (`show RUN.nc`): its attributes, output times and every observable over time with its units;
    a height at the top of the box says so (``saturated_at``, as the table's "(top: saturated)")."""
    name, description = scene_title(attrs)
    observables = {}
    for observable, values, shown in series:
        observables[observable] = {"units": str(shown.get("units", "1")), "long_name": str(shown.get("long_name", "")),
                                   "values": np.asarray(values, dtype=float)}
        if SATURATION in shown:
            observables[observable]["saturated_at"] = shown[SATURATION]
    return {"kind": "run", "scene": name, "description": description, "status": str(attrs.get("status", "done")),
            "attributes": dict(attrs), "time": times if times is not None else [], "observables": observables}


def study_record(ds: xr.Dataset) -> dict:
    """A study.nc (`show DIR`, `sweep`): its attributes and one entry per case: id, status, the swept keys,
    cost, message, and the observables at the last output time (as the table)."""
    dims = [d.strip() for d in str(ds.attrs.get("sweep_dimensions", "case")).split(",")]
    swept = [str(c) for c in ds.coords if ds[c].dims and set(ds[c].dims) <= set(dims) and c != "case"]
    shown = shown_in_study(ds)
    columns = case_columns(ds, ("case_id", "status", *swept, "wall_time", "steps_taken", "message", *shown))
    cases = [{name: values[i] for name, values in columns.items()} for i in range(len(columns["case_id"]))]
    units = {n: str(ds[n].attrs.get("units", "1")) for n in shown}
    last = ds["time"].values[-1] if "time" in ds.coords and ds["time"].size else None
    return {"kind": "study", "attributes": dict(ds.attrs), "swept": swept, "observables_units": units,
            "time": last, "cases": cases}


def dataset_record(ds: xr.Dataset) -> dict:
    """A summary dataset (convergence.nc, stability.nc, calibration.nc, analysis.nc) whole: its attributes,
    coordinates and variables with their dimensions and units; the markdown tables are made from these."""
    coordinates = {str(c): ds[c].values for c in ds.coords}
    variables = {str(v): {"dims": list(map(str, ds[v].dims)), "units": str(ds[v].attrs.get("units", "")),
                          "values": ds[v].values} for v in ds.data_vars}
    from .error_model import recorded  # lazily: scipy's optimiser only for a convergence's recommendation

    return {"kind": "dataset", "attributes": dict(ds.attrs), "coordinates": coordinates, "variables": variables,
            **recorded(ds.attrs)}
