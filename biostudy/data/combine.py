"""A study's combined dataset, DIR/study.nc: its finished case files stacked along the sweep.

Data, not plans: a study's `Plan` is read for its cases, keys and scenes only.

One dimension per swept key (grid mode) or a `case` dimension with the swept
or sampled values as coordinates on it (zip mode, a `[sample]` design), so
``study.phi_mean.sel(g=1e10)`` works.  Every observable (`biostudy.observables`)
of every case is there per time (the series a run has itself, phi_mean, c_mean and biofilm_volume, as the
run wrote them).  Every case has its `status` (done, failed, missing) and `message`;
a case that did not finish is NaN.  Variables whose coordinates differ
between cases (fields on different grids) stay in the case files.  What does
not change over time and is the same in every case (the masks `obstacle` and
`nutrient_source` with their int8 flags, the cell bounds, the parameters not
swept) is there once, without the study's dimensions.  The attributes are the
study file, its base scene and the attributes every finished case shares.

Each case file is written in the layout it has in the study (`CaseLayout`):
its swept values as coordinates along the study's dimensions, of length 1
(grid: one per swept key; zip and sampled: `case`, with the values on it), its
status, message, wall time and steps as variables, so that
``xr.open_mfdataset("DIR/cases/*.nc")`` rebuilds the study without a
``preprocess`` (docs/results.md).
"""
from __future__ import annotations

import contextlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from solver.counters import MEANINGS
from solver.output import cf_units

from ..inputs.keys import dimension, id_text
from ..inputs.scene import key_info, overrides_text
from ..quantities import observables
from . import case_files, netcdf, netcdf_io, provenance, writing

if TYPE_CHECKING:
    from ..plans.cases import Plan

# Per-case attributes that are not shared by a study (they stay in cases/*.nc).
PER_CASE = {"case_id", "status", "message", "error", "created", "scene", "overrides", "fingerprint", "title",
            "wall_time", "steps_taken", "steps_bisected", "steps_rejected", "history", netcdf.CASE_DIMENSIONS}
CASE_VARIABLES = ("status", "message", "wall_time", "steps_taken", "case_id")  # per case, in study.nc and case files
CASE_ATTRS = {"long_name": "case id (file under cases/)", "units": "1"}


def _coordinate(key: str, values: list) -> tuple[np.ndarray, dict]:
    """Values of a swept key as a netCDF coordinate (numbers stay numbers; lists become labels).  Units
    in udunits spelling (a rate per T*: the numerator's units, `solver.output.cf_units`); the long name
    from the scene schema keeps the model's units readable."""
    long_name, units = key_info(key)
    attrs = {"long_name": f"{long_name} (swept: {key})", "units": cf_units(units)}
    if all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int8), {**attrs, "units": "1", "flag_values": np.int8([0, 1]),
                                                  "flag_meanings": "false true"}
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int64), attrs
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=float), attrs
    return np.array([v if isinstance(v, str) else id_text(v) for v in values], dtype=object), attrs


def _shared_variables(datasets: list[xr.Dataset]) -> list[str]:
    """Variables every finished case has on identical coordinates (so they stack into study.nc)."""
    first = datasets[0]
    shared = []
    for name in first.data_vars:
        var = first[name]
        if all(name in ds.data_vars and ds[name].dims == var.dims and ds[name].shape == var.shape
               and all(np.array_equal(ds[d].values, first[d].values) for d in var.dims if d in first.coords)
               for ds in datasets[1:]):
            shared.append(name)
    return shared


def _floats(ds: xr.Dataset) -> xr.Dataset:
    """Integer variables as float, so a case that did not finish can be NaN (flag values follow: CF 3.5)."""
    def floating(var: xr.DataArray) -> xr.DataArray:
        var = var.astype(float)
        if "flag_values" in var.attrs:
            var.attrs["flag_values"] = np.asarray(var.attrs["flag_values"], dtype=float)
        return var

    return ds.assign({n: floating(ds[n]) for n in ds.data_vars if not np.issubdtype(ds[n].dtype, np.floating)})


def _static(var: xr.DataArray) -> bool:
    """Not a function of time: masks, parameters."""
    return not {"time", "time_mechanics"} & set(var.dims)


def _statics_shared(plan: Plan) -> bool:
    """Whether every case has the same grid, nutrient sources and obstacles (so the same masks and cell
    bounds): decided from the scenes, before anything runs, so case files and study.nc agree."""
    return len({json.dumps(scene.model_dump(mode="json", include={"grid", "nutrient", "obstacle"}), sort_keys=True)
                for scene in plan.scenes.values()}) == 1


def _study_coordinates(plan: Plan) -> tuple[list[str], dict]:
    """The study's dimensions and its coordinates: {name: (dims, values, attrs)}."""
    keys = plan.keys
    if plan.mode == "grid":
        dims = [dimension(k) for k in keys]
        return dims, {d: (d, *_coordinate(k, plan.spec.sweep.values[k])) for d, k in zip(dims, keys)}
    coords = {"case": ("case", np.array([c.id for c in plan.cases], dtype=object), CASE_ATTRS)}
    coords.update({dimension(k): ("case", *_coordinate(k, [c.values[k] for c in plan.cases])) for k in keys})
    return ["case"], coords


@dataclass(frozen=True)
class CaseLayout:
    """A case's place in its study, as its case file records it: the study's coordinates at this case (length
    1 along each study dimension) and whether the static variables are shared by every case."""

    dims: tuple[str, ...]
    coords: dict  # name -> (dims, values of length 1, attrs)
    statics_shared: bool

    def apply(self, ds: xr.Dataset) -> xr.Dataset:
        """A run's dataset (or a failure record) in this layout: every variable that varies between cases,
        and the case's status, message, wall time, steps and id, gain the study dimensions; a swept
        parameter is a coordinate instead of a variable."""
        attrs = ds.attrs
        ds = ds.drop_vars([n for n in self.coords if n in ds.data_vars])
        scalars = _scalars(str(attrs.get("status", "done")), str(attrs.get("message", "")), attrs)
        scalars["case_id"] = ((), np.array(str(attrs.get("case_id", "")), dtype=object), CASE_ATTRS)
        ds = ds.assign(scalars)
        kept = [n for n in ds.data_vars if _static(ds[n]) and n not in scalars and self.statics_shared]
        ds = ds.assign({n: ds[n].expand_dims(list(self.dims)) for n in ds.data_vars if n not in kept})
        ds = ds.assign_coords(self.coords)
        ds.attrs = {**attrs, netcdf.CASE_DIMENSIONS: ", ".join(self.dims)}
        return ds


def with_overrides(ds: xr.Dataset, pairs: dict) -> xr.Dataset:
    """One run's dataset made with overrides (`biostudy run --set KEY=VALUE`): each overridden key a scalar
    coordinate holding its value, never a new dimension, so that a run keeps its shape however its values were
    given (the `overrides` attribute lists them too).  Runs of one scene with different values combine along a
    key with ``xr.open_mfdataset(files, combine="nested", concat_dim=KEY)`` (docs/results.md, "Looking at the
    results").  An overridden parameter
    keeps the units and long name of its variable in `ds`."""
    coords = {}
    for key, value in pairs.items():
        name = dimension(key)
        values, attrs = _coordinate(key, [value])
        coords[name] = ((), values[0], dict(ds[name].attrs) if name in ds.data_vars else attrs)
    return ds.drop_vars([name for name in coords if name in ds.data_vars]).assign_coords(coords)


def case_layouts(plan: Plan) -> dict[str, CaseLayout]:
    """The layout of every case file of a study (`CaseLayout`), by case id."""
    dims, coords = _study_coordinates(plan)
    shared = _statics_shared(plan)
    layouts = {}
    for number, case in enumerate(plan.cases):
        at = dict(zip(dims, case.index)) if plan.mode == "grid" else {"case": number}
        layouts[case.id] = CaseLayout(tuple(dims), {name: (along, values[[at[along]]], attrs)
                                                    for name, (along, values, attrs) in coords.items()}, shared)
    return layouts


def _as_run(ds: xr.Dataset, coords: dict) -> xr.Dataset:
    """A case file as its run wrote it: without the study's coordinates and the per-case variables (nor a
    swept parameter as a variable, as a case file written without its layout has it)."""
    dims = [d.strip() for d in str(ds.attrs.get(netcdf.CASE_DIMENSIONS, "")).split(",") if d.strip()]
    ds = netcdf.renamed(ds).isel({d: 0 for d in dims if d in ds.dims}, drop=True)
    return ds.drop_vars([n for n in (*CASE_VARIABLES, *coords) if n in ds.variables])


def _nest(items: list, sizes: list[int]) -> list:
    """Flat list (last index fastest) -> nested lists of the given sizes."""
    if len(sizes) == 1:
        return items
    step = len(items) // sizes[0]
    return [_nest(items[i * step:(i + 1) * step], sizes[1:]) for i in range(sizes[0])]


def _scalars(status: str, message: str, attrs: dict) -> dict:
    def number(key):
        return float(attrs.get(key, np.nan))

    return {
        "status": ((), np.array(status, dtype=object), {"long_name": "outcome of the case: done, failed "
                                                                    "or missing (not run)", "units": "1"}),
        "message": ((), np.array(message, dtype=object), {"long_name": "why the case failed", "units": "1"}),
        "wall_time": ((), number("wall_time"), {"long_name": "wall time of the simulation", "units": "s"}),
        "steps_taken": ((), number("steps_taken"), {"long_name": MEANINGS["steps_taken"], "units": "1"}),
    }


def write_study(plan: Plan, out_dir: str | Path) -> Path:
    """Combine the case files under DIR/cases/ into DIR/study.nc (atomically), case by case in memory."""
    with contextlib.ExitStack() as opened:
        return writing.write_atomic(combine(plan, out_dir, opened), Path(out_dir) / "study.nc")


def combine(plan: Plan, out_dir: str | Path, opened: contextlib.ExitStack) -> xr.Dataset:
    """study.nc: the cases stacked along one dimension per swept key (grid) or along `case` (zip).

    Case files are opened lazily (dask-backed) and registered with `opened`, which closes them: a
    sweep of many large cases is streamed into study.nc, not held in memory at once.
    """
    dims, coords = _study_coordinates(plan)
    records, datasets = _read_cases(plan, out_dir, opened, coords)
    done = list(datasets.values())
    shared = _shared_variables(done) if done else []
    statics_shared = _statics_shared(plan)
    once = [n for n in shared if _static(done[0][n]) and statics_shared]  # written once, as they are
    shared = [n for n in shared if n not in once]
    parts = _case_parts(plan, records, datasets, shared)
    if plan.mode == "grid":
        sizes = [len(plan.spec.sweep.values[k]) for k in plan.keys]
        combined = xr.combine_nested(_nest(parts, sizes), concat_dim=dims, combine_attrs="override")
    else:
        combined = xr.concat(parts, dim="case", combine_attrs="override")
    combined = combined.assign_coords(coords).transpose(*dims, ...)
    if done:
        first = done[0]
        combined = combined.assign({n: first[n] for n in once})
        if statics_shared:  # the cell bounds (CF 7.1) of the grid every case shares
            combined = combined.assign_coords({n: first[n] for n in first.coords if n not in combined.coords})
    omitted = sorted({n for ds in done for n in ds.data_vars} - set(shared) - set(once))
    combined.attrs = _study_attrs(plan, done, [records[c.id][0] for c in plan.cases], omitted)
    return combined


def _read_cases(plan: Plan, out_dir: str | Path, opened: contextlib.ExitStack,
                coords: dict) -> tuple[dict[str, tuple[str, str, dict]], dict[str, xr.Dataset]]:
    """Every case's (status, message, recorded attributes), and the dataset of every finished one as its run wrote
    it, measured as its scene measures now, with every observable its fields give (those it has are kept)."""
    records, datasets = {}, {}
    for case in plan.cases:
        path = case_files.case_file(out_dir, case.id)
        record = case_files.recorded(path) or {}
        status = str(record.get("status", "missing"))
        if status == "done":
            ds = _as_run(opened.enter_context(netcdf_io.open_dataset(path, chunks={})), coords)
            ds = observables.as_measured(ds, plan.scenes[case.id].substratum_attrs())
            datasets[case.id] = ds.assign({k: v for k, v in observables.variables(ds).items() if k not in ds})
        records[case.id] = (status, str(record.get("message", "")), record)
    return records, datasets


def _case_parts(plan: Plan, records: dict[str, tuple[str, str, dict]], datasets: dict[str, xr.Dataset],
                shared: list[str]) -> list[xr.Dataset]:
    """One dataset per case, in the plan's order: its `shared` variables (NaN where the case did not finish) and
    its status, message, wall time, steps and id."""
    template = _floats(next(iter(datasets.values()))[shared]) if datasets else None
    parts = []
    for case in plan.cases:
        status, message, record = records[case.id]
        if case.id in datasets:
            part = _floats(datasets[case.id][shared])
            attrs = datasets[case.id].attrs
        else:
            part = xr.full_like(template, np.nan) if template is not None else xr.Dataset()
            attrs = record  # a failure record has the wall time until it failed
        part.attrs = {}
        part = part.assign(_scalars(status, message, attrs))
        part["case_id"] = ((), np.array(case.id, dtype=object), CASE_ATTRS)
        parts.append(part)
    return parts


def _study_attrs(plan: Plan, done: list[xr.Dataset], statuses: list[str], omitted: list[str]) -> dict:
    """study.nc's attributes: what every finished case shares (but the swept keys), the study and its base scene,
    the counts of cases by status, the variables left in the case files, and the provenance."""
    keys = plan.keys
    swept = {dimension(k) for k in keys} | {k.split(".")[-1] for k in keys}  # e.g. g, advection, grid_shape
    common = {k: v for k, v in _common_attrs([ds.attrs for ds in done]).items() if k not in swept}
    return provenance.with_provenance({
        **common,
        "title": f"biofilm growth study: {plan.spec.name}",
        "study": plan.file.read_text(encoding="utf-8"),
        "study_file": str(plan.file.resolve()),
        "scene": plan.base.to_toml(),
        "scene_file": str(plan.scene_file.resolve()),
        "overrides": overrides_text(plan.common),
        "sweep_mode": plan.mode,
        "sweep_keys": ", ".join(keys),
        "sweep_dimensions": ", ".join(dimension(k) for k in keys) if plan.mode == "grid" else "case",
        "cases": len(plan.cases),
        "cases_done": statuses.count("done"),
        "cases_failed": statuses.count("failed"),
        "cases_missing": statuses.count("missing"),
        **(plan.spec.sample.attrs() if plan.mode == "sample" else {}),
        "omitted_variables": ", ".join(omitted) + " (coordinates differ between cases: see cases/)"
        if omitted else "",
    })


def _common_attrs(attrs: list[dict]) -> dict:
    """Attributes equal in every finished case (swept parameters and per-case counters drop out)."""
    if not attrs:
        return {}
    common = {}
    for name, value in attrs[0].items():
        if name in PER_CASE or name.startswith("wall_time_"):
            continue
        if all(name in a and np.array_equal(np.asarray(a[name], dtype=object), np.asarray(value, dtype=object))
               for a in attrs[1:]):
            common[name] = value
    return common
