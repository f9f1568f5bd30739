"""Datasets on disk: atomic netCDF writes, case records for resuming, the combined study.nc.

A file is complete or absent (SPEC 5): every dataset is written to a hidden
temporary file in the target directory, flushed to disk (fsync), then
renamed over the final name (`os.replace` is atomic within a filesystem).
A run killed mid-write leaves only a ``.NAME.PID.XXXX.tmp`` file, which the
next sweep in that directory removes.

A sweep keeps one file per case, ``DIR/cases/<case id>.nc``: the dataset of
a finished run (``status = "done"``) or, for a run that failed, a record
with no variables (``status = "failed"``, ``message`` says why).  Each
carries a fingerprint of the compiled problem, so re-running a study skips
exactly the cases whose inputs have not changed.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import importlib.metadata
import os
import secrets
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import xarray as xr

from .errors import BadInput
from .scene import Scene, key_info, overrides_text
from .study import Plan, dimension, label

if TYPE_CHECKING:
    import solver

TMP_GLOB = ".*.tmp"
# Per-case attributes that are not shared by a study (they stay in cases/*.nc).
PER_CASE = {"case_id", "status", "message", "error", "created", "scene", "overrides", "fingerprint", "title",
            "wall_time", "steps_taken", "steps_bisected", "steps_rejected"}


def version() -> str:
    try:
        return importlib.metadata.version("biostudy")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def legal_attrs(attrs: dict) -> dict:
    """Attributes netCDF can store: no None, booleans as 0/1, nested dicts flattened to 'a_b' names."""
    legal = {}
    for name, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, dict):
            legal.update(legal_attrs({f"{name}_{k}": v for k, v in value.items()}))
        elif isinstance(value, (bool, np.bool_)):
            legal[name] = int(value)
        elif isinstance(value, (list, tuple)):
            legal[name] = ", ".join(map(str, value)) if any(isinstance(v, str) for v in value) else np.asarray(value)
        elif isinstance(value, Path):
            legal[name] = str(value)
        else:
            legal[name] = value
    return legal


def fingerprint(problem: "solver.Problem") -> str:
    """sha256 of everything that determines a run's result (not its name)."""
    digest = hashlib.sha256()
    for part in (problem.grid, problem.params, problem.numerics, problem.mechanics, problem.consumption,
                 problem.t_end, problem.steps):
        digest.update(repr(part).encode())
    for array in (problem.phi0, problem.nutrient_fixed, problem.nutrient_value, problem.obstacle,
                  problem.output_times):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def stamp(ds: xr.Dataset, scene: Scene, scene_file: str | Path, overrides: str, **extra: Any) -> xr.Dataset:
    """The run's dataset with what produced it: the scene as TOML text, its file, the overrides."""
    ds = ds.copy()
    ds.attrs.update({"scene": scene.to_toml(), "scene_file": str(Path(scene_file).resolve()),
                     "overrides": overrides, "biostudy_version": version(), "created": now(), **extra})
    ds.attrs = legal_attrs(ds.attrs)
    return ds


def write_atomic(ds: xr.Dataset, path: str | Path) -> Path:
    """Write `ds` to `path` as netCDF4: temporary file beside it, fsync, rename; nothing else on failure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        ds.to_netcdf(temporary, engine="netcdf4", format="NETCDF4")
        with open(temporary, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    try:
        directory = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(directory)
        finally:
            os.close(directory)
    except OSError:
        pass  # directories cannot be fsynced on every platform; the rename itself is done
    return path


def remove_temporaries(directory: str | Path) -> list[Path]:
    """Delete temporary files a killed run left behind (never a file under a final name)."""
    removed = []
    for leftover in Path(directory).glob(TMP_GLOB):
        leftover.unlink(missing_ok=True)
        removed.append(leftover)
    return removed


def open_dataset(path: str | Path) -> xr.Dataset:
    """A result file, loaded into memory and closed; an unreadable file is `BadInput`."""
    path = Path(path)
    if not path.is_file():
        raise BadInput("no such file", path)
    try:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            return ds.load()
    except (OSError, ValueError) as error:
        raise BadInput(f"not a netCDF dataset ({str(error).splitlines()[0]})", path) from None


# ---------------------------------------------------------------------------------------------
# Sweep records


def case_file(out_dir: str | Path, case_id: str) -> Path:
    return Path(out_dir) / "cases" / f"{case_id}.nc"


def recorded(path: str | Path) -> dict | None:
    """The status attributes of a case file, or None if there is none or it cannot be read."""
    import netCDF4

    if not Path(path).is_file():
        return None
    try:
        with netCDF4.Dataset(path) as nc:
            return {name: nc.getncattr(name) for name in ("status", "message", "error", "fingerprint", "wall_time")
                    if name in nc.ncattrs()}
    except OSError:
        return None


def failure_record(message: str, seconds: float, scene: Scene, scene_file: Path, overrides: str,
                   **extra: Any) -> xr.Dataset:
    """A failed case on disk: no variables, the reason in the attributes."""
    ds = xr.Dataset(attrs={"Conventions": "CF-1.10", "title": f"failed run: {scene.name}", "wall_time": seconds})
    return stamp(ds, scene, scene_file, overrides, status="failed", message=message, **extra)


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
    return np.array([v if isinstance(v, str) else label(v) for v in values], dtype=object), attrs


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
        return write_atomic(combine(plan, out_dir, opened), Path(out_dir) / "study.nc")


def combine(plan: Plan, out_dir: str | Path, opened: contextlib.ExitStack) -> xr.Dataset:
    """study.nc: the cases stacked along one dimension per swept key (grid) or along `case` (zip).

    Case files are opened lazily (dask-backed) and registered with `opened`, which closes them: a
    sweep of many large cases is streamed into study.nc, not held in memory at once.
    """
    records, datasets = {}, {}
    for case in plan.cases:
        path = case_file(out_dir, case.id)
        record = recorded(path) or {}
        status = str(record.get("status", "missing"))
        if status == "done":
            datasets[case.id] = opened.enter_context(xr.open_dataset(path, engine="netcdf4", chunks={}))
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
        sizes = [len(plan.study.sweep.values[k]) for k in keys]
        combined = xr.combine_nested(_nest(parts, sizes), concat_dim=dims, combine_attrs="override")
        combined = combined.assign_coords({d: (d, *_coordinate(k, plan.study.sweep.values[k]))
                                           for d, k in zip(dims, keys)})
        combined = combined.transpose(*dims, ...)
    else:
        combined = xr.concat(parts, dim="case", combine_attrs="override")
        combined = combined.assign_coords(case=("case", np.array([c.id for c in plan.cases], dtype=object),
                                                {"long_name": "case id (file under cases/)", "units": "1"}))
        combined = combined.assign_coords({dimension(k): ("case", *_coordinate(k, plan.study.sweep.values[k]))
                                           for k in keys})
    swept = {dimension(k) for k in keys} | {k.split(".")[-1] for k in keys}  # e.g. g, advection, grid_shape
    common = {k: v for k, v in _common_attrs([ds.attrs for ds in done]).items() if k not in swept}
    omitted = sorted({n for ds in done for n in ds.data_vars} - set(shared))
    statuses = [records[c.id][0] for c in plan.cases]
    combined.attrs = legal_attrs({
        **common,
        "title": f"biofilm growth study: {plan.study.name}",
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
        "omitted_variables": ", ".join(omitted) + " (coordinates differ between cases: see cases/)"
        if omitted else "",
        "biostudy_version": version(),
        "created": now(),
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
