"""`biostudy show A.nc B.nc [...]`: runs side by side.

Everything comes from the files: the scenes they record (the keys that
differ), the model parameters, every observable at the output times all runs
share (the first, a middle one and the last of them), and, where two runs
have the same grid, the largest difference of each field from the first run
over those times: how large, at which T* and in which cell.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from rich.console import Group
from rich.table import Table
from rich.text import Text

from solver.problem import parameter_infos

from ..formatting import number, units_text, value_text
from ..inputs.keys import flatten
from ..quantities import observables

CELL_DIMS = ("z", "y", "x")
FIELDS = ("phi", "c", "alpha", "p")
SHOWN_TIMES = 3  # common output times shown: the first, a middle one, the last


@dataclass(frozen=True)
class Difference:
    """The largest |field - first run's field| over the common times: its size, where and when."""

    field: str
    run: int  # index of the run compared with the first
    largest: float
    time: float
    cell: dict  # axis -> cell centre (µm)
    units: str


def _scene(ds: xr.Dataset) -> dict:
    try:
        return flatten(tomllib.loads(str(ds.attrs.get("scene", ""))))
    except tomllib.TOMLDecodeError:
        return {}


def scene_differences(runs: list[xr.Dataset]) -> dict[str, list]:
    """Every scene key whose value differs between the runs' recorded scenes: key -> value in each run."""
    scenes = [_scene(ds) for ds in runs]
    keys = sorted(set().union(*scenes))
    missing = object()
    return {key: [s.get(key, missing) for s in scenes] for key in keys
            if len({repr(s.get(key, missing)) for s in scenes}) > 1}


def _shared(first, *others) -> np.ndarray:
    """The times of `first` that every one of `others` has too (to 1e-9 relative)."""
    times = np.asarray(first, dtype=float)
    for other in others:
        other = np.asarray(other, dtype=float)
        times = times[[bool(np.isclose(other, t, rtol=1e-9, atol=1e-12).any()) for t in times]]
    return times


def common_times(runs: list[xr.Dataset]) -> np.ndarray:
    """The output times every run has."""
    return _shared(*(ds["time"].values for ds in runs))


def _at(ds: xr.Dataset, times: np.ndarray, dim: str = "time") -> list[int]:
    values = np.asarray(ds[dim].values, dtype=float)
    return [int(np.argmin(np.abs(values - t))) for t in times]


def _same_grid(a: xr.Dataset, b: xr.Dataset) -> bool:
    dims = [d for d in CELL_DIMS if d in a.dims]
    return dims == [d for d in CELL_DIMS if d in b.dims] and all(
        a.sizes[d] == b.sizes[d] and np.allclose(a[d].values, b[d].values) for d in dims)


def field_differences(runs: list[xr.Dataset], times: np.ndarray) -> tuple[list[Difference], list[str]]:
    """The largest difference of every field of each run from the first run's over `times` (p and u: the
    common times where both solved the mechanics); and why a run was not compared (another grid)."""
    first, found, skipped = runs[0], [], []
    for number_, ds in enumerate(runs[1:], start=1):
        if not _same_grid(first, ds):
            skipped.append(f"run {number_ + 1} has another grid than run 1: fields not compared")
            continue
        for name in FIELDS:
            if name not in first or name not in ds:
                continue
            dim = "time_mechanics" if "time_mechanics" in first[name].dims else "time"
            wanted = times if dim == "time" else _shared(first[dim].values, ds[dim].values)
            if not wanted.size:
                continue
            cells = [d for d in CELL_DIMS if d in first[name].dims]
            a = first[name].isel({dim: _at(first, wanted, dim)}).transpose(dim, *cells).values
            b = ds[name].isel({dim: _at(ds, wanted, dim)}).transpose(dim, *cells).values
            gap = np.abs(a - b)
            if not np.isfinite(gap).any():
                continue
            where = np.unravel_index(int(np.nanargmax(gap)), gap.shape)
            found.append(Difference(name, number_, float(gap[where]), float(wanted[where[0]]),
                                    {d: float(first[d].values[i]) for d, i in zip(cells, where[1:])},
                                    str(first[name].attrs.get("units", "1"))))
    return found, skipped


def _observables(ds: xr.Dataset) -> dict[str, xr.DataArray]:
    computed = observables.variables(ds) if "phi" in ds else {}
    return {name: ds[name] if name in ds and ds[name].dims == ("time",) else values
            for name, values in computed.items()}


def _shown(value) -> str:
    return "(absent)" if not isinstance(value, (int, float, str, bool, list)) else value_text(value)


@dataclass(frozen=True)
class Comparison:
    """How two or more runs differ (module docstring): the scene keys (key -> value in each run), the output
    times all share, the largest field differences from the first run, and why a run's fields were not
    compared."""

    scenes: dict[str, list]
    times: np.ndarray
    fields: list[Difference]
    skipped: list[str]


def comparison(runs: list[xr.Dataset]) -> Comparison:
    """What `compare` shows of `runs`, as numbers."""
    times = common_times(runs)
    found, skipped = field_differences(runs, times) if times.size else ([], [])
    return Comparison(scene_differences(runs), times, found, skipped)


def compare(runs: list[xr.Dataset], paths: list[Path], found: Comparison | None = None) -> Group:
    """The side-by-side summary of two or more runs (module docstring); `found`: their `comparison`, if made."""
    found = found or comparison(runs)
    columns = [f"run {i + 1}" for i in range(len(runs))]
    head = Table(show_edge=False, title="runs")
    head.add_column("")
    head.add_column("file")
    head.add_column("scene")
    head.add_column("wall s", justify="right")
    head.add_column("steps", justify="right")
    for label, path, ds in zip(columns, paths, runs):
        scene = _scene(ds)
        head.add_row(label, str(path), str(scene.get("name", "?")), number(ds.attrs.get("wall_time")),
                     number(ds.attrs.get("steps_taken")))
    parts = [head]

    differences = found.scenes
    table = Table(show_edge=False, title="scene keys that differ")
    table.add_column("key")
    for label in columns:
        table.add_column(label)
    for key, values in differences.items():
        table.add_row(key, *(_shown(v) for v in values))
    parts.append(table if differences else Text("the scenes are the same"))

    params = Table(show_edge=False, title="parameters")
    params.add_column("parameter")
    for label in columns:
        params.add_column(label, justify="right")
    for info in parameter_infos():
        values = [ds.attrs.get(info.name) for ds in runs]
        style = "bold" if len({repr(v) for v in values}) > 1 else None
        params.add_row(f"{info.name} ({units_text(info.units) or '1'})", *(number(v, 6) for v in values), style=style)
    parts.append(params)

    times = found.times
    if times.size:
        picks = sorted({0, times.size // 2, times.size - 1})[:SHOWN_TIMES]
        shown = times[picks]
        series = [_observables(ds) for ds in runs]
        obs = Table(show_edge=False, title="observables at output times all runs share")
        obs.add_column("observable")
        obs.add_column("units")
        for t in shown:
            for label in columns:
                obs.add_column(f"T* = {number(t)}\n{label}", justify="right")
        for name in observables.REGISTRY:
            if not all(name in s for s in series):
                continue
            values = [number(s[name].values[_at(ds, np.array([t]))[0]]) for t in shown for s, ds in zip(series, runs)]
            obs.add_row(name, units_text(series[0][name].attrs["units"]), *values)
        parts.append(obs)
        fields = Table(show_edge=False, title="largest field differences from run 1")
        for column in ("field", "run", "largest |difference|", "units", "at T*", "cell (µm)"):
            fields.add_column(column, justify="right" if column in ("largest |difference|", "at T*") else "left")
        for d in found.fields:
            fields.add_row(d.field, columns[d.run], number(d.largest, exponent=True), units_text(d.units) or "1",
                           number(d.time), ", ".join(f"{k} = {number(v)}" for k, v in reversed(d.cell.items())))
        parts.append(fields)
        parts.extend(Text(line) for line in found.skipped)
    else:
        parts.append(Text("the runs share no output time: observables and fields not compared"))
    return Group(*parts)
