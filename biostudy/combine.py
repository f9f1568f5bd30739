"""A study's combined dataset, DIR/study.nc: its finished case files stacked along the sweep.

One dimension per swept key (grid mode) or a `case` dimension with the swept
or sampled values as coordinates on it (zip mode, a `[sample]` design), so
``study.phi_mean.sel(g=1e10)`` works.  Every observable (`biostudy.observables`)
of every case is there per time (the series a run has itself, phi_mean, c_mean and biofilm_volume, as the
run wrote them).  Every case has its `status` (done, failed, missing) and `message`;
a case that did not finish is NaN.  Variables whose coordinates differ
between cases (fields on different grids) stay in the case files.  The
attributes are the study file, its base scene and the attributes every
finished case shares.
"""
from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import xarray as xr

from . import observables, store
from .scene import key_info, overrides_text
from .study import Plan, dimension, id_text

# Per-case attributes that are not shared by a study (they stay in cases/*.nc).
PER_CASE = {"case_id", "status", "message", "error", "created", "scene", "overrides", "fingerprint", "title",
            "wall_time", "steps_taken", "steps_bisected", "steps_rejected"}


def _coordinate(key: str, values: list) -> tuple[np.ndarray, dict]:
    """Values of a swept key as a netCDF coordinate (numbers stay numbers; lists become labels)."""
    long_name, units = key_info(key)
    attrs = {"long_name": f"{long_name} (swept: {key})", "units": units}
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
    """Integer variables as float, so a case that did not finish can be NaN."""
    return ds.assign({n: ds[n].astype(float) for n in ds.data_vars if not np.issubdtype(ds[n].dtype, np.floating)})


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
        "steps": ((), number("steps_taken"), {"long_name": "accepted time steps", "units": "1"}),
        "bisections": ((), number("steps_bisected"), {"long_name": "bisected (failed) time steps", "units": "1"}),
    }


def write_study(plan: Plan, out_dir: str | Path) -> Path:
    """Combine the case files under DIR/cases/ into DIR/study.nc (atomically), case by case in memory."""
    with contextlib.ExitStack() as opened:
        return store.write_atomic(combine(plan, out_dir, opened), Path(out_dir) / "study.nc")


def combine(plan: Plan, out_dir: str | Path, opened: contextlib.ExitStack) -> xr.Dataset:
    """study.nc: the cases stacked along one dimension per swept key (grid) or along `case` (zip).

    Case files are opened lazily (dask-backed) and registered with `opened`, which closes them: a
    sweep of many large cases is streamed into study.nc, not held in memory at once.
    """
    records, datasets = {}, {}
    for case in plan.cases:
        path = store.case_file(out_dir, case.id)
        record = store.recorded(path) or {}
        status = str(record.get("status", "missing"))
        if status == "done":
            ds = opened.enter_context(xr.open_dataset(path, engine="netcdf4", chunks={}))
            datasets[case.id] = ds.assign({k: v for k, v in observables.variables(ds).items() if k not in ds})
        records[case.id] = (status, str(record.get("message", "")), record)
    done = list(datasets.values())
    shared = _shared_variables(done) if done else []
    template = None
    if done:
        template = _floats(done[0][shared])
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
        part["case_id"] = ((), np.array(case.id, dtype=object), {"long_name": "case id (file under cases/)",
                                                                 "units": "1"})
        parts.append(part)

    keys = plan.keys
    if plan.mode == "grid":
        dims = [dimension(k) for k in keys]
        sizes = [len(plan.spec.sweep.values[k]) for k in keys]
        combined = xr.combine_nested(_nest(parts, sizes), concat_dim=dims, combine_attrs="override")
        combined = combined.assign_coords({d: (d, *_coordinate(k, plan.spec.sweep.values[k]))
                                           for d, k in zip(dims, keys)})
        combined = combined.transpose(*dims, ...)
    else:
        combined = xr.concat(parts, dim="case", combine_attrs="override")
        combined = combined.assign_coords(case=("case", np.array([c.id for c in plan.cases], dtype=object),
                                                {"long_name": "case id (file under cases/)", "units": "1"}))
        combined = combined.assign_coords({dimension(k): ("case", *_coordinate(k, [c.values[k] for c in plan.cases]))
                                           for k in keys})
    swept = {dimension(k) for k in keys} | {k.split(".")[-1] for k in keys}  # e.g. g, advection, grid_shape
    common = {k: v for k, v in _common_attrs([ds.attrs for ds in done]).items() if k not in swept}
    omitted = sorted({n for ds in done for n in ds.data_vars} - set(shared))
    statuses = [records[c.id][0] for c in plan.cases]
    combined.attrs = store.with_provenance({
        **common,
        "title": f"biofilm growth study: {plan.spec.name}",
        "study": plan.file.read_text(encoding="utf-8"),
        "study_file": str(plan.file.resolve()),
        "scene": plan.base.to_toml(),
        "scene_file": str(plan.scene_file.resolve()),
        "overrides": overrides_text(plan.fixed),
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
    return combined


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
