"""`biostudy show`: a readable summary of a run's dataset, a failed case's record or a study.nc.

Everything shown comes from the file itself (attributes and time series),
so a result can be understood without the scene file that produced it.  A run
made with ``--error-estimate`` shows each observable as Q ± Q_error (its
estimated discretisation error; "± ?" where the estimate could not be made,
the row "error bars" says why).
"""
from __future__ import annotations

import tomllib
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Group
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from solver.problem import parameter_infos

from ..data import real_time
from ..data.incomplete import INCOMPLETE
from ..formatting import number, units_text
from ..inputs.substratum_face import LEFT_OUT
from ..quantities.saturation import SATURATION, saturated

if TYPE_CHECKING:
    import xarray as xr

AVERAGES = ("phi_mean", "c_mean", "biofilm_volume")  # what a study.nc written before observables has


def _rows(rows: list[tuple[str, str]]) -> Table:
    table = Table.grid(padding=(0, 2))
    table.add_column(style="bold")
    table.add_column()
    for name, value in rows:
        if value:
            table.add_row(name, value)
    return table


def scene_title(attrs: dict) -> tuple[str, str]:
    try:
        scene = tomllib.loads(str(attrs.get("scene", "")))
    except tomllib.TOMLDecodeError:
        scene = {}
    return str(scene.get("name", "?")), str(scene.get("description", ""))


def _from_scene(attrs: dict) -> dict:
    """Grid, model and parameters from the recorded scene text, where the run left none (a failed case)."""
    try:
        scene = tomllib.loads(str(attrs.get("scene", "")))
    except tomllib.TOMLDecodeError:
        return {}
    grid = scene.get("grid", {})
    found = {"grid_shape": grid.get("shape"), "grid_spacing": grid.get("spacing"),
             **{key: scene.get("model", {}).get(name) for key, name in (("consumption", "consumption"),
                ("expansion", "expansion"), ("nutrient_dynamics", "nutrient"))},
             "advection": scene.get("numerics", {}).get("advection"),
             "growth_velocity": scene.get("numerics", {}).get("growth_velocity"), **scene.get("params", {})}
    return {k: v for k, v in found.items() if v is not None}


def _header(attrs: dict) -> list[tuple[str, str]]:
    attrs = {**_from_scene(attrs), **attrs} if "grid_shape" not in attrs else attrs
    shape = np.atleast_1d(attrs.get("grid_shape", []))
    grid = " × ".join(str(int(n)) for n in shape)
    rows = [
        ("scene file", str(attrs.get("scene_file", ""))),
        ("overrides", str(attrs.get("overrides", "")).replace("\n", "; ")),
    ]
    if grid:
        rows.append(("grid", f"{grid} cells of {number(attrs.get('grid_spacing'))} µm"))
    model = [f"{k.replace('_', ' ')} {attrs[k]}" for k in ("consumption", "expansion", "nutrient_dynamics", "advection",
                                                                "growth_velocity", "mechanics")
             if k in attrs]
    if "nutrient_faces" in attrs:
        model.append(f"nutrient held on {attrs['nutrient_faces']}")
    rows.append(("model", ", ".join(model)))
    params = [f"{p.name} = {number(attrs[p.name])}{' ' + units_text(p.units) if units_text(p.units) else ''}"
              for p in parameter_infos() if p.name in attrs]
    rows.append(("parameters", ", ".join(params)))
    return rows


def _software(attrs: dict) -> str:
    versions = [f"{k.removeprefix('version_').replace('_', '-')} {v}" for k, v in attrs.items()
                if k.startswith("version_")]
    return ", ".join([f"biostudy {attrs.get('biostudy_version', '?')}", *versions])


def run_series(ds: xr.Dataset) -> tuple[dict, np.ndarray | None, list[tuple[str, np.ndarray, dict]]]:
    """A run's attributes, output times and observables (name, values over time, their attributes)."""
    if "time" not in ds.dims or "phi" not in ds:
        return ds.attrs, None, []
    from ..quantities import observables  # lazily: a file that holds its observables needs none of this

    series = [(name, values.values, with_error(values.attrs, ds, name))
              for name, values in observables.variables(ds).items()]
    return ds.attrs, ds.time.values, series


ERROR = "error"  # the key of an observable's shown attributes that holds its Q_error values, when the run has them


def with_error(attrs: dict, ds: xr.Dataset, name: str) -> dict:
    """An observable's attributes for `summary_of`, with its error bars' values (`ERROR`) when the run has them."""
    if f"{name}_error" not in ds:
        return dict(attrs)
    return {**attrs, ERROR: np.asarray(ds[f"{name}_error"].values, dtype=float).reshape(-1)}


def run_summary(ds: xr.Dataset) -> Group:
    """One run: scene, parameters, cost, and the observables at the start and the end."""
    return summary_of(*run_series(ds))


def _value(values: np.ndarray, index: int, attrs: dict) -> str:
    """One value of an observable, ± its estimated error where the run has error bars; a height at the top of the
    box marked saturated (a lower bound)."""
    text = number(values[index])
    if ERROR in attrs:
        error = attrs[ERROR][index]
        text += f" ± {number(error)}" if np.isfinite(error) else (" ± ?" if np.isfinite(values[index]) else "")
    return text + " (top: saturated)" if saturated(values[index], attrs.get(SATURATION)) else text


def _cost(attrs: dict) -> str:
    """Wall time, steps taken, bisected and shortened to the Courant limit, and the largest Courant number."""
    text = f"wall time {number(attrs.get('wall_time'))} s"
    if "steps_taken" not in attrs:
        return text
    text += f", steps {attrs['steps_taken']} taken, {attrs.get('steps_bisected', '-')} bisected"
    if "steps_substepped" in attrs:
        text += f", {attrs['steps_substepped']} shortened to the scheme's limit"
    if "courant_max" in attrs:
        text += f", largest Courant number {number(attrs['courant_max'], 3)}"
    return text


def summary_of(attrs: dict, times: np.ndarray | None, series: list[tuple[str, np.ndarray, dict]]) -> Group:
    """One run from its attributes, output times and observables (name, values over time, their attributes)."""
    name, description = scene_title(attrs)
    status = str(attrs.get("status", "done"))
    rows = _header(attrs)
    if status != "done":
        rows.append(("status", f"[red]{status}[/red]: {attrs.get('message', '')}"))
    elif attrs.get(INCOMPLETE):
        rows.append(("status", f"[red]incomplete[/red]: {escape(str(attrs[INCOMPLETE]))}"))
    rows += [
        ("run", _cost(attrs)),
        ("COMSTAT", escape(str(attrs.get(LEFT_OUT, "")))),
        ("created", str(attrs.get("created", ""))),
        ("software", _software(attrs)),
    ]
    if "error_estimate" in attrs:
        cost = attrs.get("error_estimate_wall_time")
        rows.append(("error bars", str(attrs["error_estimate"]) + (f" (companions: wall time {number(cost)} s)"
                                                                   if cost is not None else "")))
    parts = [Text.from_markup(f"[bold]{name}[/bold]" + (f" — {description}" if description else "")), _rows(rows)]
    if times is not None:
        table = Table(title=None, show_edge=False)
        table.add_column("observable")
        table.add_column(real_time.shown(attrs, float(times[0])), justify="right")
        table.add_column(real_time.shown(attrs, float(times[-1])), justify="right")
        table.add_column("units")
        table.add_column("meaning")
        for name, values, shown in series:
            table.add_row(name, _value(values, 0, shown), _value(values, -1, shown),
                          units_text(shown.get("units", "1")), str(shown.get("long_name", "")))
        parts.append(table)
    return Group(*parts)


def study_summary(ds: xr.Dataset) -> Group:
    """A study.nc: what was swept, how many cases finished, one row per case."""
    attrs = ds.attrs
    dims = [d.strip() for d in str(attrs.get("sweep_dimensions", "case")).split(",")]
    rows = [("study file", str(attrs.get("study_file", ""))), *_header(attrs)]
    names = [n.strip() for n in str(attrs.get("sweep_keys", "")).split(",") if n.strip()]
    swept = [c for c in ds.coords if ds[c].dims and set(ds[c].dims) <= set(dims) and c != "case"]
    values = [f"{c} = " + ", ".join(number(v) for v in np.unique(ds[c].values)) for c in swept]
    rows += [
        ("sweep", f"{attrs.get('sweep_mode')} over {', '.join(names)}"),
        ("values", "; ".join(values)),
        ("cases", f"{attrs.get('cases')} cases: {attrs.get('cases_done')} done, {attrs.get('cases_failed')} "
                  f"failed, {attrs.get('cases_missing')} missing"),
        ("created", str(attrs.get("created", ""))),
        ("software", _software(attrs)),
    ]
    name = str(attrs.get("title", "study")).removeprefix("biofilm growth study: ")
    shown = shown_in_study(ds)
    table = Table(show_edge=False, caption="observables at the last output time (" + ", ".join(
        f"{n} {units_text(ds[n].attrs.get('units', '1')) or '1'}" for n in shown) + "; `biostudy analyze` for all)")
    table.add_column("case", no_wrap=True)
    table.add_column("status", no_wrap=True)
    for column in ("wall s", "steps", *shown):
        table.add_column(column, justify="right")
    table.add_column("message")

    columns = case_columns(ds, ("case_id", "status", "wall_time", "steps_taken", "message", *shown))
    for i, case in enumerate(columns["case_id"]):
        status = str(columns["status"][i])
        colour = {"done": "green", "failed": "red"}.get(status, "yellow")
        table.add_row(str(case), f"[{colour}]{status}[/{colour}]", number(columns["wall_time"][i]),
                      number(columns["steps_taken"][i]),
                      *(_value(columns[v], i, ds[v].attrs) if v in columns else "-" for v in shown),
                      str(columns["message"][i]))
    return Group(Text.from_markup(f"[bold]{name}[/bold]"), _rows(rows), table)


def shown_in_study(ds: xr.Dataset) -> list[str]:
    """The observables a study's summary shows (those the study has)."""
    from ..quantities import observables  # lazily: `show` at a glance needs none (reports.glance)

    return [n for n in observables.SUMMARY if n in ds] or [n for n in AVERAGES if n in ds]


def case_columns(ds: xr.Dataset, names) -> dict[str, np.ndarray]:
    """The study's variables of these names (those it has), one entry per case in the order of the
    study's dimensions; a time series at its last output."""
    dims = [d.strip() for d in str(ds.attrs.get("sweep_dimensions", "case")).split(",")]

    def flat(var: str) -> np.ndarray:
        values = ds[var]
        if "time" in values.dims:
            values = values.isel(time=-1)
        if not set(dims) <= set(values.dims):  # a swept key's coordinate: along its own dimension only
            values = values.broadcast_like(ds["case_id"])
        return values.transpose(*dims, ...).values.ravel()

    return {v: flat(v) for v in names if v in ds}


def summary(ds: xr.Dataset) -> Group:
    """What `show` prints of a dataset read whole: a study.nc's summary, or a run's."""
    return study_summary(ds) if "sweep_mode" in ds.attrs else run_summary(ds)
