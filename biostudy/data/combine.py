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

Each case file is written in the layout it has in the study (`case_files.CaseLayout`, made here:
`case_layouts`; grid: one dimension per swept key; zip and sampled: `case`, with the values on it).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from solver.output import cf_units

from ..inputs.keys import dimension, id_text
from ..inputs.scene import key_info, overrides_text
from . import case_files, netcdf, provenance, study_arrays, study_cases, study_fill, writing
from .case_files import CASE_ATTRS, CaseLayout, static
from .study_arrays import nest, stack

if TYPE_CHECKING:
    from ..plans.cases import Plan

# Per-case attributes that are not shared by a study (they stay in cases/*.nc).
PER_CASE = {"case_id", "status", "message", "error", "created", "scene", "overrides", "fingerprint", "title",
            "wall_time", "steps_taken", "steps_bisected", "steps_rejected", "history", netcdf.CASE_DIMENSIONS}


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
    axes = [d for d in first.dims if d in first.coords]
    same = [{d for d in axes if d in ds.coords and np.array_equal(ds[d].values, first[d].values)}
            for ds in datasets[1:]]  # the coordinates each case has as the first has them
    shared = []
    for name, var in first.data_vars.items():
        if all(name in ds.data_vars and ds.variables[name].dims == var.dims and ds.variables[name].shape == var.shape
               and all(d in equal for d in var.dims if d in first.coords)
               for ds, equal in zip(datasets[1:], same)):
            shared.append(name)
    return shared


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


def write_study(plan: Plan, out_dir: str | Path) -> Path:
    """Combine the case files under DIR/cases/ into DIR/study.nc (atomically); the fields stacked along the study
    are written case by case once the rest is (not through dask: its store of thousands of lazy reads costs time
    that grows with their square), each case's compressed chunks copied as they are (`study_fill`)."""
    combined, cases = _combined(plan, out_dir, True)  # its fields unread: `study_fill` copies them
    dims, _ = _study_coordinates(plan)
    stacked = [name for name, var in combined.data_vars.items()
               if var.chunks is not None and tuple(var.dims[:len(dims)]) == tuple(dims)]

    places = [(tuple(case.index) if plan.mode == "grid" else (number,), cases[case.id])
              for number, case in enumerate(plan.cases)]
    return writing.write_atomic(combined, Path(out_dir) / "study.nc",
                                deferred=(stacked, lambda path: study_fill.fill(path, stacked, places)))


def combine(plan: Plan, out_dir: str | Path) -> xr.Dataset:
    """study.nc: the cases stacked along one dimension per swept key (grid) or along `case` (zip).

    Each case file's observables, coordinates and attributes are read at once, its fields lazily
    (`study_cases`): a sweep of many large cases is streamed into study.nc, not held in memory at once.
    """
    return _combined(plan, out_dir)[0]


def _combined(plan: Plan, out_dir: str | Path, unread: bool = False) -> tuple[xr.Dataset, dict[str, study_cases.Case]]:
    """study.nc's dataset and the cases read; `unread`: its fields stacked from the common study's cases read
    nothing (`study_arrays.stacked`: `write_study` fills them case by case)."""
    dims, coords = _study_coordinates(plan)
    reader = study_cases.Reader(coords)
    cases = {case.id: reader.read(case_files.case_file(out_dir, case.id), plan.scenes[case.id].substratum_attrs())
             for case in plan.cases}
    statics_shared = _statics_shared(plan)
    sizes = [len(plan.spec.sweep.values[k]) for k in plan.keys] if plan.mode == "grid" else [len(plan.cases)]
    first = reader.template.run if reader.template is not None else None
    once = [n for n in first.data_vars if static(first[n]) and statics_shared] if first is not None else []
    combined = study_arrays.stacked(reader, list(cases.items()), dims, sizes, once, unread)
    if combined is None:  # cases of different layouts or coordinates: a dataset per case
        cases = {case_id: reader.dataset(found) for case_id, found in cases.items()}
        done = [case.run for case in cases.values() if case.run is not None]
        shared = _shared_variables(done) if done else []
        once = [n for n in shared if static(done[0][n]) and statics_shared]  # written once, as they are
        shared = [n for n in shared if n not in once]
        parts = _case_parts(plan, cases, shared)
        combined = _stacked(parts, dims, sizes)
        if combined is None:
            combined = xr.combine_nested(nest(parts, sizes), concat_dim=dims, combine_attrs="override")
        first = done[0] if done else None
        found = [set(ds.data_vars) for ds in done]
        done_attrs = [ds.attrs for ds in done]
    else:
        shared = [n for n in first.data_vars if n not in once]
        found = [set(first.data_vars)]
        done_attrs = [case.run.attrs if case.run is not None else {**case.attrs, **case.now}
                      for case in cases.values() if case.status == "done"]
    combined = combined.assign_coords(coords).transpose(*dims, ...)
    if first is not None:
        combined = combined.assign({n: first[n] for n in once})
        if statics_shared:  # the cell bounds (CF 7.1) of the grid every case shares
            combined = combined.assign_coords({n: first[n] for n in first.coords if n not in combined.coords})
    omitted = sorted(set().union(*found) - set(shared) - set(once))
    combined.attrs = _study_attrs(plan, done_attrs, [cases[c.id].status for c in plan.cases], omitted)
    return combined, cases


def _stacked(parts: list[xr.Dataset], dims: list[str], sizes: list[int]) -> xr.Dataset | None:
    """The cases' datasets stacked along the study's dimensions (of `sizes`, the last fastest) variable by variable:
    what `xr.combine_nested` makes of them where every case has the same variables and coordinates (None
    elsewhere), without its alignment of every case (most of the time of combining many small cases)."""
    first = parts[0]
    names = list(first.data_vars)
    if any(list(part.data_vars) != names or not _same_coordinates(part, first) for part in parts[1:]):
        return None
    variables = {}
    for name in names:
        var = first.variables[name]
        data = stack(nest([part.variables[name].data for part in parts], sizes))
        variables[name] = xr.Variable([*dims, *var.dims], data, dict(var.attrs), dict(var.encoding))
    return xr.Dataset(variables, first.coords)


def _same_coordinates(ds: xr.Dataset, other: xr.Dataset) -> bool:
    return list(ds.coords) == list(other.coords) and all(
        ds[n].dims == other[n].dims and np.array_equal(ds[n].values, other[n].values) for n in ds.coords)


def _case_parts(plan: Plan, cases: dict[str, study_cases.Case], shared: list[str]) -> list[xr.Dataset]:
    """One dataset per case, in the plan's order (`study_arrays.part`)."""
    runs = [case.run for case in cases.values() if case.run is not None]
    template = study_arrays.floats(runs[0][shared]) if runs else None
    return [study_arrays.part(cases[case.id], case.id, shared, template) for case in plan.cases]


def _study_attrs(plan: Plan, done: list[dict], statuses: list[str], omitted: list[str]) -> dict:
    """study.nc's attributes: what every finished case shares (but the swept keys), the study and its base scene,
    the counts of cases by status, the variables left in the case files, and the provenance."""
    keys = plan.keys
    swept = {dimension(k) for k in keys} | {k.split(".")[-1] for k in keys}  # e.g. g, advection, grid_shape
    common = {k: v for k, v in _common_attrs(done).items() if k not in swept}
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
        if all(name in a and _equal(a[name], value) for a in attrs[1:]):
            common[name] = value
    return common


def _equal(a, b) -> bool:
    """Two attribute values equal, element by element (NaN is not); text and single numbers of one type compared
    at once (most of a thousand cases' attributes)."""
    if type(a) is type(b) and isinstance(a, (str, int, float, np.integer, np.floating)):
        return bool(a == b)
    return bool(np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object)))
